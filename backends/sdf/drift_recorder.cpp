#include "drift_recorder.hpp"

#include <algorithm>
#include <cmath>

namespace pinsim::sdf {
namespace {

void put(double* out, const Vec2& v) {
  out[0] = v.x();
  out[1] = v.y();
}
void put(double* out, const Eigen::Matrix2d& m) {
  for (int c = 0; c < 4; ++c) out[c] = m(c % 2, c / 2);
}

/// Central differences' steps: in space relative to the point's size (the gradient's
/// rounding, ~1e-16, over 2e-6 gives ~1e-10; the truncation is eps^2 / 6 times the third
/// derivative), in time 1e-7 s.
constexpr double kSpaceStep = 1e-6;
constexpr double kTimeStep = 1e-7;

}  // namespace

void DriftRecorder::set(const pinsim_drift_sink* sink) {
  on_ = sink != nullptr;
  sink_ = on_ ? *sink : pinsim_drift_sink{};
}

void DriftRecorder::begin(const MutableState& s, double dt) {
  t0_ = s.t;
  dt_ = dt;
  pairs_ = 0;
  change_ids_.assign(s.n, {});
  const pinsim_state_view view{
      s.n, s.t, s.x.data(), s.v.data(), s.inv_mass.data(), s.radius.data()};
  if (sink_.begin) sink_.begin(sink_.context, &view, dt);
}

void DriftRecorder::pair(uint32_t i, uint32_t j, double tau, const Vec2& xr_i, const Vec2& vc_i,
                         double tr_i, const Vec2& xr_j, const Vec2& vc_j, double tr_j,
                         double radius_sum, double w_i, double w_j, double restitution) {
  pinsim_drift_pair h{};
  h.i = i;
  h.j = j;
  h.tau = tau;
  put(h.xr_i, xr_i);
  put(h.vc_i, vc_i);
  h.tr_i = tr_i;
  put(h.xr_j, xr_j);
  put(h.vc_j, vc_j);
  h.tr_j = tr_j;
  h.radius_sum = radius_sum;
  h.w_i = w_i;
  h.w_j = w_j;
  h.restitution = restitution;
  // already overlapping where both tracks start (the schedule's c <= 0: tau is that time)
  const double t = std::max(tr_i, tr_j);
  const Vec2 dx = (xr_i + vc_i * (t - tr_i)) - (xr_j + vc_j * (t - tr_j));
  h.touching = dx.squaredNorm() - radius_sum * radius_sum <= 0.0 ? 1u : 0u;
  if (w_i > 0.0) change_ids_[i].emplace_back(pairs_, 0);
  if (w_j > 0.0) change_ids_[j].emplace_back(pairs_, 1);
  ++pairs_;
  if (sink_.pair) sink_.pair(sink_.context, &h);
}

void DriftRecorder::change(std::size_t i, std::size_t c, double tau, const Vec2& x,
                           const Vec2& v_before, const Vec2& v_after) {
  pinsim_drift_impact m{};
  m.kind = PINSIM_IMPACT_CHANGE;
  m.particle = static_cast<int64_t>(i);
  m.obstacle = -1;
  m.pair = change_ids_[i][c].first;
  m.side = change_ids_[i][c].second;
  m.tau = tau;
  put(m.p, x);
  put(m.v_before, v_before);
  put(m.v_after, v_after);
  if (sink_.impact) sink_.impact(sink_.context, &m);
}

void DriftRecorder::impact(const ObstacleField& field, std::size_t i, std::size_t k, bool toi,
                           double t, const Vec2& x, const Vec2& v_before, const Vec2& v_after,
                           double offset, bool resting, bool emitted) {
  const Obstacle& o = field.obstacle(k);
  const bool moving = o.motion != MotionType::kStatic;
  const Sdf sd = field.eval(k, x, t);
  const Vec2 n = sd.g;
  const Vec2 pc = x - sd.d * n;
  // n_p = d n / d p: the SDF's Hessian, column j = (g(x + e_j h) - g(x - e_j h)) / 2h
  const double h = kSpaceStep * std::max(1.0, x.cwiseAbs().maxCoeff());
  Eigen::Matrix2d n_p, u_p = Eigen::Matrix2d::Zero();
  for (int j = 0; j < 2; ++j) {
    const Vec2 e = Vec2::Unit(j) * h;
    n_p.col(j) = (field.eval(k, x + e, t).g - field.eval(k, x - e, t).g) / (2.0 * h);
    if (moving)
      u_p.col(j) = (field.velocity(k, pc + e, t) - field.velocity(k, pc - e, t)) / (2.0 * h);
  }
  Vec2 n_t = Vec2::Zero(), u = Vec2::Zero(), u_t = Vec2::Zero();
  if (moving) {
    u = field.velocity(k, pc, t);
    n_t =
        (field.eval(k, x, t + kTimeStep).g - field.eval(k, x, t - kTimeStep).g) / (2.0 * kTimeStep);
    u_t = (field.velocity(k, pc, t + kTimeStep) - field.velocity(k, pc, t - kTimeStep)) /
          (2.0 * kTimeStep);
  }
  pinsim_drift_impact m{};
  m.kind = toi ? uint32_t{PINSIM_IMPACT_TOI} : uint32_t{PINSIM_IMPACT_IN_BAND};
  m.flags = (resting ? uint32_t{PINSIM_IMPACT_RESTING} : 0u) |
            (emitted ? uint32_t{PINSIM_IMPACT_EMITTED} : 0u);
  m.particle = static_cast<int64_t>(i);
  m.obstacle = static_cast<int64_t>(k);
  m.pair = -1;
  m.tau = t - t0_;
  put(m.p, x);
  put(m.v_before, v_before);
  put(m.v_after, v_after);
  put(m.n, n);
  put(m.n_p, n_p);
  put(m.n_t, n_t);
  m.phi = sd.d;
  m.phi_t = -n.dot(u);  // a rigid motion moves the field at p by u(p), and u(p) - u(pc) _|_ n
  m.offset = offset;
  put(m.u, u);
  put(m.u_p, u_p);
  put(m.u_t, u_t);
  m.restitution = o.material.restitution;
  m.friction = o.material.friction;
  m.kick = o.material.kick;
  if (sink_.impact) sink_.impact(sink_.context, &m);
  // a time of impact at the very start or end of the step: a perturbation moves it into the
  // neighbouring step, where the integrator's kick comes before it
  const double edge = std::min(m.tau, dt_ - m.tau);
  if (toi && edge < 1e-9 * dt_) finding(PINSIM_FINDING_STEP_END, i, m.obstacle, t, edge);
}

void DriftRecorder::finding(uint32_t kind, std::size_t i, int64_t obstacle, double t,
                            double margin) {
  const pinsim_drift_finding f{kind, static_cast<int64_t>(i), obstacle, t, margin};
  if (sink_.finding) sink_.finding(sink_.context, &f);
}

}  // namespace pinsim::sdf
