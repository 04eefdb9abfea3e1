// Velocity Verlet, with the position update done by the backend.
#include "core/integrators.hpp"
#include "core/step_context.hpp"

namespace pinsim {
namespace {

/// Velocity Verlet, kick/2 - drift - kick/2:
///   v_{n+1/2} = v_n + h/2 M^-1 f(x_n);  x_{n+1} = x_n + h v_{n+1/2};
///   v_{n+1} = v_{n+1/2} + h/2 M^-1 f(x_{n+1}).
/// Second order; exact (to rounding) for constant forces. A contact inside the drift
/// reflects v_{n+1/2}, not the velocity at the time of impact v_n + tau M^-1 f_n;
/// correct_impacts fixes the impulse so a bounce keeps the method second order.
/// Velocity-dependent forces (damping): the closing half kick needs f(x_{n+1}, v_{n+1}), and
/// f(x_{n+1}, v_{n+1/2}) is off by O(h), which leaves the method first order. One predictor
///   v* = v_{n+1/2} + h/2 M^-1 f(x_{n+1}, v_{n+1/2}),
///   v_{n+1} = v_{n+1/2} + h/2 M^-1 f(x_{n+1}, v*)
/// makes the force error O(h^2) and restores second order, at one more force evaluation per
/// step, spent only when a force is dissipative (or declares no energy, so may depend on v).
class VelocityVerlet : public Integrator {
 public:
  Kick before_drift(StepContext& ctx, double h) override {
    if (!checked_) {
      checked_ = true;
      for (const auto& f : ctx.forces())
        velocity_dependent_ = velocity_dependent_ || f->velocity_dependent();
    }
    ctx.compute_forces(ctx.state(), f_);
    return {&f_, 0.5 * h};
  }
  ImpactReference impact_reference(const State& s, double h) override {
    accelerations(s, f_, a_);
    return {&a_, 0.5 * h};
  }
  bool acts_after_drift() const override { return true; }
  void after_drift(StepContext& ctx, double h) override {
    State& s = ctx.state();
    ctx.compute_forces(s, f_);
    if (velocity_dependent_) {
      predicted_ = s;
      kick(predicted_, f_, 0.5 * h);
      ctx.compute_forces(predicted_, f_);
    }
    kick(s, f_, 0.5 * h);
  }

 private:
  Eigen::Matrix2Xd f_, a_;
  State predicted_;
  bool checked_ = false, velocity_dependent_ = false;
};

}  // namespace

std::unique_ptr<Integrator> make_velocity_verlet() { return std::make_unique<VelocityVerlet>(); }

}  // namespace pinsim
