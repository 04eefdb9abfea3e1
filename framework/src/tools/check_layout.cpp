#include "tools/check_layout.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace pinsim {

namespace {

/// Bodies built by the scene's own generators (so their element sets and order are the
/// ones scenes get), with the element sets that play each arity's part.
struct TopologySpec {
  std::vector<nlohmann::json> bodies;
  std::map<uint32_t, std::vector<std::string>> sets;  ///< arity -> set names, in order
  double noise;
};

const std::map<std::string, TopologySpec>& topology_specs() {
  using J = nlohmann::json;
  static const std::map<std::string, TopologySpec> specs = {
      // A closed ring of 8: edges (i, i+1) and triples wrap around; whole body = the ring.
      {"ring",
       {{J{{"type", "ring_blob"}, {"center", {0.0, 0.0}}, {"ring_radius", 0.8}, {"count", 8}}},
        {{1, {"particles"}}, {2, {"edges"}}, {3, {"triples"}}, {0, {"boundary"}}},
        0.15}},
      // A 4 x 3 grid: rows and columns, diagonals, straight triples; whole body = outline.
      {"grid",
       {{J{{"type", "grid_blob"},
           {"origin", {-0.75, -0.5}},
           {"nx", 4},
           {"ny", 3},
           {"spacing", 0.5}}},
        {{1, {"particles"}}, {2, {"edges", "shear"}}, {3, {"triples"}}, {0, {"boundary"}}},
        0.12}},
      // Two bodies of different sizes with every pair set; whole bodies of 7 and 9
      // particles (the grid's in index order, not its outline).
      {"body",
       {{J{{"type", "ring_blob"}, {"center", {-1.0, 0.0}}, {"ring_radius", 0.6}, {"count", 7}},
         J{{"type", "grid_blob"}, {"origin", {0.4, -0.5}}, {"nx", 3}, {"ny", 3}, {"spacing", 0.5}}},
        {{1, {"particles"}},
         {2, {"edges", "cross", "shear", "bend"}},
         {3, {"triples"}},
         {0, {"body"}}},
        0.12}},
  };
  return specs;
}

std::string arity_text(uint32_t arity) {
  return arity == 0 ? std::string("whole-body elements")
                    : "elements of arity " + std::to_string(arity);
}

}  // namespace

const std::vector<std::string>& check_topologies() {
  static const std::vector<std::string> t = {"chain", "ring", "grid", "body"};
  return t;
}

CheckLayout topology_layout(const std::string& topology_in, uint32_t arity) {
  const std::string topology =
      !topology_in.empty() ? topology_in : (arity == 0 ? std::string("ring") : "chain");
  CheckLayout l;
  l.arity = arity;
  if (topology == "chain") {
    // Random points; a sliding window over them (an open chain of pairs, a strand's
    // triples) plus, for pairs, two extra ones; for whole bodies one open chain.
    l.n = std::max<std::size_t>(6, (arity == 0 ? 8 : arity + 4));
    if (arity == 0) {
      l.elements.push_back(static_cast<uint32_t>(l.n));
      for (uint32_t i = 0; i < l.n; ++i) l.elements.push_back(i);
    } else if (arity == 1) {
      for (uint32_t i = 0; i < l.n; ++i) l.elements.push_back(i);
    } else {
      for (uint32_t i = 0; i + arity <= l.n; ++i)
        for (uint32_t k = 0; k < arity; ++k) l.elements.push_back(i + k);
      if (arity == 2)
        l.elements.insert(l.elements.end(),
                          {0, static_cast<uint32_t>(l.n - 1), 1, static_cast<uint32_t>(l.n - 2)});
    }
    l.count = element_count(l.elements, arity);
    l.description = "topology chain: " + std::to_string(l.count) + " " + arity_text(arity) +
                    " on " + std::to_string(l.n) + " random particles";
    return l;
  }
  const auto it = topology_specs().find(topology);
  if (it == topology_specs().end()) {
    std::string known;
    for (const auto& t : check_topologies()) known += (known.empty() ? "" : ", ") + t;
    throw InputError("--topology " + topology + ": unknown topology (known: " + known + ")");
  }
  const TopologySpec& spec = it->second;
  const auto sets = spec.sets.find(arity);
  if (sets == spec.sets.end())
    throw InputError("--topology " + topology + ": has no " + arity_text(arity) +
                     " (it has arity 1, 2, 3 and whole bodies)");
  ParticleList particles;
  std::vector<std::string> used;
  for (std::size_t b = 0; b < spec.bodies.size(); ++b) {
    const Body body =
        build_body(spec.bodies[b], "check-plugin: bodies[" + std::to_string(b) + "]", particles);
    for (const auto& name : sets->second) {
      const auto s = body.sets.find(name);
      if (s == body.sets.end()) continue;
      l.elements.insert(l.elements.end(), s->second.indices.begin(), s->second.indices.end());
      if (std::find(used.begin(), used.end(), name) == used.end()) used.push_back(name);
    }
  }
  l.n = particles.size();
  l.x.resize(2, static_cast<Eigen::Index>(l.n));
  for (std::size_t i = 0; i < l.n; ++i) l.x.col(static_cast<Eigen::Index>(i)) = particles.x[i];
  l.noise = spec.noise;
  l.count = element_count(l.elements, arity);
  std::string names;
  for (const auto& u : used) names += (names.empty() ? "" : ", ") + u;
  l.description = "topology " + topology + ": " + std::to_string(l.count) + " " +
                  arity_text(arity) + " (" + names + ") on " + std::to_string(l.n) + " particles";
  return l;
}

CheckLayout scene_layout(const Scene& scene, std::size_t index, uint32_t arity) {
  if (index >= scene.forces.size())
    throw InputError(scene.label + ": --force-index " + std::to_string(index) + ": the scene has " +
                     std::to_string(scene.forces.size()) + " force(s)");
  const ForceSpec& f = scene.forces[index];
  CheckLayout l;
  l.arity = arity;
  l.elements = scene.resolve_elements(f, arity);
  l.count = element_count(l.elements, arity);
  const State s = scene.initial_state();
  l.n = static_cast<std::size_t>(s.x.cols());
  l.x = s.x;
  l.v = s.v;
  l.inv_mass = s.inv_mass;
  l.radius = s.radius;
  // Perturbation: a fifth of the mean nearest-neighbour distance (0.1 for one particle).
  double sum = 0.0;
  for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (Eigen::Index j = 0; j < s.x.cols(); ++j)
      if (j != i) best = std::min(best, (s.x.col(i) - s.x.col(j)).norm());
    if (std::isfinite(best)) sum += best;
  }
  l.noise = l.n > 1 && sum > 0.0 ? 0.2 * sum / static_cast<double>(l.n) : 0.1;
  l.description = f.where + " (" + f.name + "): " + std::to_string(l.count) + " " +
                  arity_text(arity) + " on the scene's " + std::to_string(l.n) + " particles";
  return l;
}

}  // namespace pinsim
