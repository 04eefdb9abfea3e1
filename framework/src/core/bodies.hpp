// Bodies: scene entries that generate particles and named element sets
// (a ring blob's "edges", a strand's "triples", ...).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace pinsim {

/// A list of elements of one arity: indices.size() == arity * count.
struct ElementSet {
  uint32_t arity = 0;
  std::vector<uint32_t> indices;
  std::size_t count() const { return arity == 0 ? 0 : indices.size() / arity; }
};

/// Particles being collected while a scene is parsed.
struct ParticleList {
  std::vector<Eigen::Vector2d> x, v;
  std::vector<double> inv_mass, radius;
  /// Appends one particle and returns its index.
  uint32_t add(const Eigen::Vector2d& pos, const Eigen::Vector2d& vel, double inv_m, double r) {
    x.push_back(pos);
    v.push_back(vel);
    inv_mass.push_back(inv_m);
    radius.push_back(r);
    return static_cast<uint32_t>(x.size() - 1);
  }
  std::size_t size() const { return x.size(); }
};

/// A generated body: its particle range and named element sets (particle indices global).
struct Body {
  std::string name;
  std::string type;
  uint32_t first = 0;  ///< index of the body's first particle
  uint32_t count = 0;  ///< number of particles
  std::map<std::string, ElementSet> sets;
};

/// Builds the body described by `spec` (an entry of the scene's "bodies" array), appending
/// its particles to `particles`. `where` is the location for errors, e.g.
/// "blob.json: bodies[1]"; errors are SceneError naming the key and what was expected.
Body build_body(const nlohmann::json& spec, const std::string& where, ParticleList& particles);

/// The body types build_body knows, for messages and the schema.
std::vector<std::string> body_types();

}  // namespace pinsim
