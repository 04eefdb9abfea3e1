// The gradient of a loss of a scene's run in values named by --set paths: the run forward
// with checkpoints (the same steps as `pinsim run`), then the adjoint steps backward over
// replayed segments, with the scene's own plugins and backend (docs/gradients.md).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "gradients/losses.hpp"
#include "gradients/step_adjoint.hpp"

namespace pinsim::grad {

/// One value named by a --wrt path, as the scene has it.
struct WrtValue {
  enum class Kind : uint8_t {
    kPosition,        ///< particles[I].x: the initial position of an explicit particle
    kVelocity,        ///< particles[I].v: its initial velocity
    kForceParameter,  ///< forces[K].params.NAME: a real or 2-vector parameter of a force
    kMaterial,        ///< obstacles[K].material.NAME: restitution, friction or kick of an obstacle
    kBodyPosition,    ///< bodies[K].center (.origin, .root): where a body is built
    kBodyVelocity     ///< bodies[K].velocity: the initial velocity of its free particles
  };
  std::string path;  ///< as given, e.g. "forces[1].params.ks"
  Kind kind = Kind::kVelocity;
  std::size_t index = 0;  ///< the particle, the force, the obstacle or the body
  /// The particles a position or velocity value moves, all by the same amount: the one
  /// particle, or a body's particles (for its velocity, those not pinned).
  std::vector<uint32_t> particles;
  std::string param;                           ///< the parameter's or material's name
  std::vector<double> value;                   ///< its components
  double lower = -HUGE_VAL, upper = HUGE_VAL;  ///< its bounds (the plugin's parameter table)
};

/// The values `paths` name in `scene`, whose simulation is `sim`. Throws InputError naming
/// the path for a path the scene does not have, or one that is not differentiable (with the
/// paths that are).
std::vector<WrtValue> resolve_wrt(const Scene& scene, const Simulation& sim,
                                  const std::vector<std::string>& paths);

/// The loss of a run, made once the run's size is known.
using LossFactory = std::function<std::unique_ptr<Loss>(const LossContext&)>;

struct GradientOptions {
  RunOptions run;        ///< as for `pinsim run` (--integrator, --threads)
  uint64_t segment = 0;  ///< steps between checkpoints; 0: ceil(sqrt(steps))
  /// Relative step of the central differences of a force in its parameters (and in the
  /// initial positions its rest values come from): eps = rel_eps max(|theta|, 1).
  double rel_eps = 1e-6;
  /// A force's derivative in a parameter from its plugin (add_dforce_dparam, ABI 4.4) where
  /// the plugin gives it; false: central differences for every parameter.
  bool plugin_parameter_derivatives = true;
};

/// The gradient of one value.
struct PathGradient {
  WrtValue wrt;
  Eigen::VectorXd gradient;  ///< d loss / d value, one per component
  /// A force parameter's derivative came from its plugin (add_dforce_dparam), not from
  /// finite differences.
  bool plugin_derivative = false;
};

/// What scene_gradient found.
struct GradientReport {
  std::string loss_text;
  double loss = 0.0;
  std::vector<PathGradient> paths;
  std::vector<Finding> findings;  ///< where the run is not differentiable (the first kMaxFindings)
  uint64_t findings_count = 0;    ///< all of them
  uint64_t impacts = 0;           ///< velocity changes of the drifts differentiated through
  static constexpr std::size_t kMaxFindings = 100;
  std::string backend, integrator;
  uint64_t steps = 0, segment = 0, checkpoints = 0, peak_states = 0;
  /// Implicit Euler: the most 2x2 blocks of a step's system that a step record held (the
  /// replay's A^T, kept for the adjoint step); 0 otherwise.
  uint64_t system_blocks = 0;
  double forward_s = 0.0, backward_s = 0.0;                    ///< wall time of each pass
  uint64_t forward_force_evals = 0, backward_force_evals = 0;  ///< force sums over all forces
  uint64_t jacobian_evals = 0;                                 ///< Jacobian assemblies (backward)
  uint64_t dparam_evals = 0;  ///< calls of the plugins' add_dforce_dparam (backward)
  uint64_t fused_evals = 0;   ///< calls of the plugins' add_adjoint_products (backward)
  AdjointStats stats;
  uint64_t state_hash = 0;  ///< of the final state: the one `pinsim run` reaches
  double rel_eps = 0.0;     ///< of the parameter derivatives
  /// Largest difference of a replayed segment's end from the forward run, relative to the
  /// state's size: 0 for the explicit integrators, within the solve's tolerance for
  /// implicit Euler.
  double replay_deviation = 0.0;
  bool any_parameter = false;

  /// gradient.json's content.
  nlohmann::json to_json() const;
};

/// The gradient of loss(run of `scene`) in the values `wrt` names. Throws InputError for a
/// bad path, an integrator without an adjoint step or a backend that cannot differentiate
/// its step (naming it); NumericError if the run fails as `pinsim run` would.
GradientReport scene_gradient(const Scene& scene, PluginLoader& loader,
                              const std::vector<std::string>& wrt, const LossFactory& loss,
                              const GradientOptions& options = {});

}  // namespace pinsim::grad
