// The two Euler methods of the seed, with the position update done by the backend.
#include "core/integrators.hpp"
#include "core/step_context.hpp"

namespace pinsim {
namespace {

/// Symplectic (semi-implicit) Euler, kick then drift:
///   v_{n+1} = v_n + h M^-1 f(x_n, v_n);  x_{n+1} = x_n + h v_{n+1} (by the backend).
/// For constant gravity y_N = y_0 + v_0 T - g T^2/2 - g h T/2: first order, error -g h T/2.
class SymplecticEuler : public Integrator {
 public:
  Kick before_drift(StepContext& ctx, double h) override {
    ctx.compute_forces(ctx.state(), f_);
    return {&f_, h};  // the kick; the drift then ends the step
  }

 private:
  Eigen::Matrix2Xd f_;
};

/// Forward (explicit) Euler, drift then kick:
///   x_{n+1} = x_n + h v_n (backend, resolving contacts);  v_{n+1} = v_n + h M^-1 f(x_n, v_n).
/// First order. On the harmonic oscillator the energy grows by exactly (1 + (h w)^2) per
/// step: unstable for every h without damping.
class ExplicitEuler : public Integrator {
 public:
  Kick before_drift(StepContext& ctx, double /*h*/) override {
    const State& s = ctx.state();
    ctx.compute_forces(s, f_);
    accelerations(s, f_, a_);
    return {};
  }
  bool acts_after_drift() const override { return true; }
  void after_drift(StepContext& ctx, double h) override {
    State& s = ctx.state();
    per_particle(s.v.cols(), [&](Eigen::Index b, Eigen::Index n) {
      s.v.middleCols(b, n) += h * a_.middleCols(b, n);
    });
  }

 private:
  Eigen::Matrix2Xd f_, a_;
};

}  // namespace

std::unique_ptr<Integrator> make_symplectic_euler() { return std::make_unique<SymplecticEuler>(); }
std::unique_ptr<Integrator> make_explicit_euler() { return std::make_unique<ExplicitEuler>(); }

}  // namespace pinsim
