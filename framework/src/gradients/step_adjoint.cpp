// Adjoint steps of the explicit integrators: symplectic Euler and velocity Verlet.
#include "gradients/step_adjoint.hpp"

#include <algorithm>

namespace pinsim::grad {
namespace {

/// w = c M^-1 g per particle (0 for pinned particles, inv_mass 0), into w's storage.
void scaled_by_inv_mass(const State& s, const Eigen::Matrix2Xd& g, double c, Eigen::Matrix2Xd& w) {
  w.resize(2, g.cols());
  for (Eigen::Index i = 0; i < g.cols(); ++i) w.col(i) = (c * s.inv_mass[i]) * g.col(i);
}

/// out = a state with s's masses and radii at (x, v) (out's storage reused).
const State& at(const State& s, const Eigen::Matrix2Xd& x, const Eigen::Matrix2Xd& v, State& out) {
  out.t = s.t;
  out.x = x;
  out.v = v;
  out.inv_mass = s.inv_mass;
  out.radius = s.radius;
  return out;
}

using Part = ForceModel::Part;

/// Adds the pending product of the position-only forces into gx and gp.
void flush_pending(ForceModel& forces, Adjoint& a, Eigen::Matrix2Xd& gx) {
  if (!a.pending) return;
  Eigen::Matrix2Xd& unused = a.scratch.unused;
  unused.setZero(2, a.pending_w.cols());
  forces.vjp_with_params(Part::kPositionOnly, a.pending_at, a.pending_w, gx, unused, a.gp);
  a.pending = false;
}

}  // namespace

bool scheme_for(const std::string& integrator, Scheme& out, std::string& why) {
  if (integrator == "symplectic_euler") {
    out = Scheme::kSymplecticEuler;
  } else if (integrator == "velocity_verlet") {
    out = Scheme::kVelocityVerlet;
  } else if (integrator == "implicit_euler") {
    out = Scheme::kImplicitEuler;
  } else {
    why = "integrator '" + integrator +
          "' has no adjoint step (differentiable: symplectic_euler, velocity_verlet, "
          "implicit_euler)";
    return false;
  }
  return true;
}

void Adjoint::reset(Eigen::Index n, Eigen::Index p) {
  gx.setZero(2, n);
  gv.setZero(2, n);
  gp.setZero(p);
  material = MaterialGrad{};
  pending = false;
  scratch.mu.resize(0);
}

void adjoint_finish(ForceModel& forces, Adjoint& a) { flush_pending(forces, a, a.gx); }

void adjoint_symplectic_euler(ForceModel& forces, const StepTape& tape, double h, Adjoint& a) {
  // (x1, v1) = drift(x0, v'), v' = v0 + h M^-1 f(x0, v0)
  drift_adjoint(tape.drift, a.gx, a.gv, nullptr, a.material);
  // the kick: a.gv is v' 's adjoint, and v0 passes through the kick unchanged
  Eigen::Matrix2Xd& w = a.scratch.w;
  scaled_by_inv_mass(tape.start, a.gv, h, w);
  forces.vjp_with_params(Part::kAll, tape.start, w, a.gx, a.gv, a.gp);
}

// Forward (integrator_verlet.cpp, correct_impacts in impact_correction.cpp):
//   f0 = f(x0, v0), vh = v0 + h/2 M^-1 f0, (x1, vd) = drift(x0, vh),
//   vc = vd - sum over emitted impacts k of particle i: c_k (tau_k - h/2) (a0_i.n_k) n_k,
//        a0 = M^-1 f0, c_k = clamp((vn_after - vn_before) / -vn_before, 1, 2)
//           = clamp(1 + e + kick / -vn_before, 1, 2),
//   f1 = f(x1, vc); with the predictor vp = vc + h/2 M^-1 f1 and f2 = f(x1, vp), else f2 = f1;
//   v1 = vc + h/2 M^-1 f2.
// With a model that splits, the forces that depend on the positions only have the same
// Jacobians and parameter derivatives at (x1, vp), (x1, vc) and the next step's (x1, v1):
// their products of those kicks are one product, at x1, of the sum of the kicks' w (the next
// step's part comes in as Adjoint::pending). The velocity-dependent forces' products stay
// one per kick.
void adjoint_velocity_verlet(ForceModel& forces, const StepTape& tape, double h, Adjoint& a) {
  const State& s0 = tape.start;
  const Eigen::Index np = s0.x.cols();
  const bool split = forces.splits();
  const Part kick_part = split ? Part::kVelocityDependent : Part::kAll;
  if (split && a.pending && a.pending_at.x != tape.x1) flush_pending(forces, a, a.gx);
  Adjoint::Scratch& sc = a.scratch;
  const State& s1 = at(s0, tape.x1, tape.vc, sc.s1);
  Eigen::Matrix2Xd& gx1 = sc.gx1;
  gx1 = a.gx;
  Eigen::Matrix2Xd& vc_bar = sc.vc_bar;
  vc_bar = a.gv;                       // v1 = vc + ...
  Eigen::Matrix2Xd& w_pos = sc.w_pos;  // split: the position-only forces' w at x1, summed
  if (split) w_pos.setZero(2, np);
  Eigen::Matrix2Xd& w = sc.w;
  // the adjoint of a kick v' = v + h/2 M^-1 f(s), given v' 's adjoint vbar
  auto kick = [&](const State& s, const Eigen::Matrix2Xd& vbar, Eigen::Matrix2Xd& gv_out) {
    scaled_by_inv_mass(s, vbar, 0.5 * h, w);
    forces.vjp_with_params(kick_part, s, w, gx1, gv_out, a.gp);
    if (split) w_pos += w;
  };
  if (tape.predicted) {
    // v1 = vc + h/2 M^-1 f(x1, vp), vp = vc + h/2 M^-1 f(x1, vc)
    const State& sp = at(s0, tape.x1, tape.vp, sc.s2);
    Eigen::Matrix2Xd& vp_bar = sc.vp_bar;
    vp_bar.setZero(2, np);
    kick(sp, a.gv, vp_bar);
    vc_bar += vp_bar;
    kick(s1, vp_bar, vc_bar);
  } else {
    kick(s1, a.gv, vc_bar);
  }
  if (split) {
    if (a.pending) {
      w_pos += a.pending_w;
      a.pending = false;
    }
    forces.vjp_with_params(Part::kPositionOnly, s1, w_pos, gx1, vc_bar, a.gp);
  }
  // the impact correction: vd passes, the impacts' own values and a0 get adjoints
  const DriftTape& d = tape.drift;
  std::vector<ImpactSeed> seeds;
  Eigen::Matrix2Xd& a0_bar = sc.a0_bar;
  a0_bar.setZero(2, np);
  bool any = false;
  for (const Impact& m : d.impacts) any = any || m.emitted;
  if (any) {
    Eigen::Matrix2Xd f0;
    forces.force(s0, f0);
    seeds.assign(d.impacts.size(), ImpactSeed{});
    for (std::size_t k = 0; k < d.impacts.size(); ++k) {
      const Impact& m = d.impacts[k];
      const auto i = static_cast<Eigen::Index>(m.particle);
      if (!m.emitted || m.obstacle < 0 || !(s0.inv_mass[i] > 0.0)) continue;
      const double vn_b = (m.v_before - m.u).dot(m.n);
      const double vn_a = (m.v_after - m.u).dot(m.n);
      if (!(vn_b < 0.0)) continue;
      const double ratio = (vn_a - vn_b) / -vn_b;
      const double c = std::clamp(ratio, 1.0, 2.0);
      const Vec2 a0 = s0.inv_mass[i] * f0.col(i);
      const double lever = m.tau - 0.5 * h;
      const double an = a0.dot(m.n);
      // vc_i -= c lever an n
      const Vec2 vb = vc_bar.col(i);
      const double cb = -m.n.dot(vb);  // adjoint of the scalar c lever an
      ImpactSeed& sd = seeds[k];
      sd.n += -c * lever * an * vb + cb * c * lever * a0;
      sd.tau += cb * c * an;
      a0_bar.col(i) += cb * c * lever * m.n;
      if (ratio >= 1.0 && ratio <= 2.0) {  // c = 1 + e + kick / -vn_b, unclamped
        const double c_bar = cb * lever * an;
        const double de = m.resting ? 0.0 : c_bar;
        const double dk = m.resting ? 0.0 : c_bar / -vn_b;
        a.material.add(m.obstacle, de, 0.0, dk);
        if (!m.resting) sd.vn += c_bar * m.kick / (vn_b * vn_b);
      }
    }
  }
  // the drift, with the correction's seeds on its impacts
  a.gx = gx1;
  drift_adjoint(d, a.gx, vc_bar, any ? &seeds : nullptr, a.material);
  // vh = v0 + h/2 M^-1 f0; a0 = M^-1 f0
  a.gv = vc_bar;
  w.resize(2, np);
  for (Eigen::Index i = 0; i < np; ++i)
    w.col(i) = (0.5 * h * s0.inv_mass[i]) * vc_bar.col(i) + (1.0 * s0.inv_mass[i]) * a0_bar.col(i);
  forces.vjp_with_params(kick_part, s0, w, a.gx, a.gv, a.gp);
  if (split) {  // the position-only forces' part: with the earlier step's kicks at x0
    a.pending_w = w;
    a.pending_at = s0;
    a.pending = true;
  }
}

void adjoint_step(Scheme scheme, ForceModel& forces, const StepTape& tape, double h, Adjoint& a,
                  AdjointStats& stats) {
  ++stats.steps;
  switch (scheme) {
    case Scheme::kSymplecticEuler:
      adjoint_symplectic_euler(forces, tape, h, a);
      return;
    case Scheme::kVelocityVerlet:
      adjoint_velocity_verlet(forces, tape, h, a);
      return;
    case Scheme::kImplicitEuler:
      adjoint_implicit_euler(forces, tape, h, a, stats);
      return;
  }
}

}  // namespace pinsim::grad
