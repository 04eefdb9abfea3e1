// Classical fourth-order Runge-Kutta, with the position update done by the backend.
#include "core/integrators.hpp"
#include "core/step_context.hpp"

namespace pinsim {
namespace {

/// Classical Runge-Kutta 4 on (x, v):
///   k1 = (v, a(x, v)),  k2 = f at (x + h/2 k1),  k3 = f at (x + h/2 k2),  k4 = f at (x + h k3),
///   (dx, dv) = h/6 (k1 + 2 k2 + 2 k3 + k4).
/// The stages are evaluated without collisions; the position update is a drift with the
/// velocity dx/h through the backend, and the velocity change the backend's contacts make
/// (v_after - dx/h) is added to v_n + dv, after correct_impacts has moved each impact's
/// reflection to the velocity at the time of impact (as for velocity Verlet): second order
/// through bounces (fourth is out of reach for a drift at one velocity). Fourth order
/// without contacts; on the harmonic oscillator |R(i y)|^2 = 1 - y^6/72 + y^8/576, y = h w,
/// stable for y <= 2 sqrt(2).
class Rk4 : public Integrator {
 public:
  Kick before_drift(StepContext& ctx, double h) override {
    State& s = ctx.state();
    const Eigen::Index n = s.x.cols();
    // Every vector update below is per particle, in fixed chunks (the same bits for any
    // thread count); B(m) is the chunk's columns of m.
    auto each = [n](auto&& body) { per_particle(n, body); };
    for (auto* m : {&x0_, &v0_, &v2_, &v3_, &vbar_, &dv_}) m->resize(2, n);
    stage_ = s;
    each([&](Eigen::Index b, Eigen::Index k) {
      x0_.middleCols(b, k) = s.x.middleCols(b, k);
      v0_.middleCols(b, k) = s.v.middleCols(b, k);
    });

    ctx.compute_forces(s, f_);
    accelerations(s, f_, a1_);

    stage_.t = s.t + 0.5 * h;
    each([&](Eigen::Index b, Eigen::Index k) {
      stage_.x.middleCols(b, k) = x0_.middleCols(b, k) + 0.5 * h * v0_.middleCols(b, k);
      stage_.v.middleCols(b, k) = v0_.middleCols(b, k) + 0.5 * h * a1_.middleCols(b, k);
      v2_.middleCols(b, k) = stage_.v.middleCols(b, k);
    });
    ctx.compute_forces(stage_, f_);
    accelerations(s, f_, a2_);

    each([&](Eigen::Index b, Eigen::Index k) {
      stage_.x.middleCols(b, k) = x0_.middleCols(b, k) + 0.5 * h * v2_.middleCols(b, k);
      stage_.v.middleCols(b, k) = v0_.middleCols(b, k) + 0.5 * h * a2_.middleCols(b, k);
      v3_.middleCols(b, k) = stage_.v.middleCols(b, k);
    });
    ctx.compute_forces(stage_, f_);
    accelerations(s, f_, a3_);

    stage_.t = s.t + h;
    each([&](Eigen::Index b, Eigen::Index k) {
      stage_.x.middleCols(b, k) = x0_.middleCols(b, k) + h * v3_.middleCols(b, k);
      stage_.v.middleCols(b, k) = v0_.middleCols(b, k) + h * a3_.middleCols(b, k);
    });
    ctx.compute_forces(stage_, f_);
    accelerations(s, f_, a4_);

    each([&](Eigen::Index b, Eigen::Index k) {
      vbar_.middleCols(b, k) = (v0_.middleCols(b, k) + 2.0 * v2_.middleCols(b, k) +
                                2.0 * v3_.middleCols(b, k) + stage_.v.middleCols(b, k)) /
                               6.0;
      dv_.middleCols(b, k) = (h / 6.0) * (a1_.middleCols(b, k) + 2.0 * a2_.middleCols(b, k) +
                                          2.0 * a3_.middleCols(b, k) + a4_.middleCols(b, k));
      s.v.middleCols(b, k) = vbar_.middleCols(b, k);
    });
    return {};  // the drift moves with vbar
  }
  // For a constant force vbar = v_n + (h/2) a_n, Verlet's drift velocity, so a contact in the
  // drift reflected the velocity of time h/2, not of the impact: the same correction (exact
  // for a constant force, O(h^2) per bounce otherwise).
  ImpactReference impact_reference(const State& /*s*/, double h) override {
    return {&a1_, 0.5 * h};
  }
  bool acts_after_drift() const override { return true; }
  // The contacts' velocity change rides on top: v_{n+1} = v_after + (v_n + dv - vbar).
  void after_drift(StepContext& ctx, double /*h*/) override {
    State& s = ctx.state();
    per_particle(s.v.cols(), [&](Eigen::Index b, Eigen::Index k) {
      s.v.middleCols(b, k) += v0_.middleCols(b, k) + dv_.middleCols(b, k) - vbar_.middleCols(b, k);
    });
  }

 private:
  State stage_;
  Eigen::Matrix2Xd f_, a1_, a2_, a3_, a4_, x0_, v0_, v2_, v3_, vbar_, dv_;
};

}  // namespace

std::unique_ptr<Integrator> make_rk4() { return std::make_unique<Rk4>(); }

}  // namespace pinsim
