// Time integrators: each splits a step into force "kicks" and the backend's "drift".
#pragma once

#include <Eigen/Core>
#include <memory>
#include <nlohmann/json.hpp>
#include <pinsim/state.hpp>
#include <string>
#include <vector>

#include "core/scene.hpp"

namespace pinsim {

class Simulation;
class StepContext;

/// The kick that ends an integrator's work before the drift, v += h M^-1 f, which
/// Simulation::step applies in one pass with the checks' copy of the velocities entering the
/// drift. No kick when f is null.
struct Kick {
  const Eigen::Matrix2Xd* f = nullptr;  ///< the forces; must live until the drift
  double h = 0.0;
};

/// What the drift's velocity was made of, for the impact correction (correct_impacts): the
/// drift moved each particle at v_n + c_h a_n. No correction when a_n is null.
struct ImpactReference {
  const Eigen::Matrix2Xd* a_n = nullptr;  ///< M^-1 f(x_n)
  double c_h = 0.0;
};

/// A time integrator as stages around the backend's drift, which Simulation::step runs in
/// this order: before_drift (forces, velocity updates) and the kick it returns; the drift;
/// the impact correction of the drift's contacts with impact_reference(); after_drift.
/// An integrator with substeps() > 1 has these stages run that many times per step, each
/// over h = dt / substeps() from its own start time, with its own drift.
/// The state moves only in these stages, and only the drift moves positions.
class Integrator {
 public:
  virtual ~Integrator() = default;
  /// Substeps per step (1 by default): the stages below run once per substep.
  virtual uint32_t substeps() const { return 1; }
  /// Forces and the velocity updates before the drift: leaves in ctx.state().v the velocity
  /// the drift moves with, but for the kick it returns (which the step then applies).
  virtual Kick before_drift(StepContext& ctx, double h) = 0;
  /// After a drift that reported contacts: the reference of their impact correction. None
  /// by default (symplectic and implicit Euler drift with the end velocity itself).
  virtual ImpactReference impact_reference(const State& /*s*/, double /*h*/) { return {}; }
  /// Whether after_drift changes the velocities. If not, the drift ends the step and the
  /// checks read the velocities leaving it from the state instead of a copy.
  virtual bool acts_after_drift() const { return false; }
  /// Velocity updates after the drift and its impact correction (closing kicks).
  virtual void after_drift(StepContext& /*ctx*/, double /*h*/) {}
  /// Figures of the integrator's own work for summary.json, or null (the default).
  virtual nlohmann::json stats() const { return nullptr; }

  /// The stages on sim's state with this integrator in place of sim's own, without
  /// Simulation::step's checks and bookkeeping (the time and the step count stay): for
  /// comparing two integrators on one scene.
  void step(Simulation& sim, double h);
};

/// The integrator called `name` (xpbd with `xpbd`'s settings); throws std::invalid_argument
/// listing the known ones.
std::unique_ptr<Integrator> make_integrator(const std::string& name, const XpbdSettings& xpbd = {});
/// Names of all integrators.
std::vector<std::string> integrator_names();

}  // namespace pinsim
