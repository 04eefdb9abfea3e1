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

/// Number of elements in `indices`: size / arity, or for arity 0 (length-prefixed
/// variable-length elements) the number of prefixes walked.
inline std::size_t element_count(const std::vector<uint32_t>& indices, uint32_t arity) {
  if (arity != 0) return indices.size() / arity;
  std::size_t n = 0;
  for (std::size_t at = 0; at < indices.size(); at += 1 + std::size_t{indices[at]}) ++n;
  return n;
}

/// A list of elements. Fixed arity: indices.size() == arity * count(). Arity 0
/// (PINSIM_ARITY_VARIABLE: whole bodies, closed rings): each element as its length L
/// followed by its L indices, exactly as pinsim_create_args passes them.
struct ElementSet {
  uint32_t arity = 0;
  std::vector<uint32_t> indices;
  std::size_t count() const { return element_count(indices, arity); }
  /// Appends one variable-length element (arity 0).
  void add_whole(const std::vector<uint32_t>& particles) {
    indices.push_back(static_cast<uint32_t>(particles.size()));
    indices.insert(indices.end(), particles.begin(), particles.end());
  }
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
/// The sets of each body type and their order are documented in docs/writing_a_plugin.md
/// ("Element sets of every body") and above each builder in bodies.cpp.
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
