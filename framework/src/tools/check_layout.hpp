// Where check-plugin's states and element lists come from: a topology (an open chain, a
// closed ring, a grid, whole bodies) built with the scene's own body generators, or a
// scene's force with its own elements and initial state.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "core/scene.hpp"

namespace pinsim {

/// The topologies `check-plugin --topology` knows, in the order the help lists them.
const std::vector<std::string>& check_topologies();

/// Particles and elements the checks run on.
struct CheckLayout {
  std::string description;         ///< for the report, e.g. "topology ring: 8 particles"
  std::size_t n = 0;               ///< particles
  uint32_t arity = 1;              ///< as the plugin declares it (0 = whole bodies)
  std::vector<uint32_t> elements;  ///< flat; length-prefixed when arity is 0
  std::size_t count = 0;           ///< number of elements
  /// Reference positions: random states perturb these by up to `noise` per coordinate.
  /// Empty: states are random points in [-1, 1]^2 (the "chain" topology).
  Eigen::Matrix2Xd x;
  double noise = 0.0;
  /// A scene's initial state (velocities, inverse masses, radii): instances are created
  /// from it, as the scene does. Empty outside --scene.
  Eigen::Matrix2Xd v;
  Eigen::VectorXd inv_mass, radius;
  bool from_scene() const { return inv_mass.size() > 0; }
};

/// The layout of a topology ("chain", "ring", "grid", "body"; "" picks chain for a fixed
/// arity and ring for whole-body plugins) for a plugin of the given arity. Throws
/// InputError for an unknown topology or one without elements of that arity.
CheckLayout topology_layout(const std::string& topology, uint32_t arity);

/// The layout of `scene.forces[index]`: its resolved elements, all the scene's particles,
/// and its initial state; states are perturbed by a fifth of the mean distance from a
/// particle to its nearest neighbour. Throws InputError naming the scene and the force.
CheckLayout scene_layout(const Scene& scene, std::size_t index, uint32_t arity);

}  // namespace pinsim
