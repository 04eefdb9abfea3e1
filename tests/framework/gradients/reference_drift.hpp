// A reference drift for the adjoint's tests: one particle against analytic obstacles (a
// half-plane, a circle, both also rotating about a pivot), impacts found as exact roots of
// phi(p + w s, t0 + s) = offset (bracketing and Newton to rounding), and particle-particle
// contacts on linear tracks as the sdf backend schedules them. It records the tapes the
// adjoint reads; central differences of it are the reference for the adjoint.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "gradients/drift_tape.hpp"

namespace pinsim::grad::testing {

inline Mat2 rot(double a) {
  Mat2 r;
  r << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
  return r;
}
inline const Mat2& skew() {  // S: the rotation by +90 degrees
  static const Mat2 s = (Mat2() << 0.0, -1.0, 1.0, 0.0).finished();
  return s;
}

struct RefObstacle {
  enum Type { kPlane, kCircle } type = kPlane;
  Vec2 a{0.0, 0.0};      ///< plane: a point on it; circle: the centre (at t = 0)
  Vec2 n0{0.0, 1.0};     ///< plane normal at t = 0
  double radius = 0.0;   ///< circle
  Vec2 pivot{0.0, 0.0};  ///< the rotation's centre
  double omega = 0.0;    ///< angular velocity, rad/s (0: static)
  double e = 1.0, mu = 0.0, kick = 0.0;

  struct Eval {
    double phi, phi_t;
    Vec2 n, n_t;
    Mat2 h;
  };
  Eval eval(const Vec2& p, double t) const {
    Eval r;
    const Mat2 rt = rot(omega * t);
    if (type == kPlane) {
      r.n = rt * n0;
      const Vec2 q = pivot + rt * (a - pivot);
      r.phi = r.n.dot(p - q);
      r.h.setZero();
      r.n_t = omega * skew() * r.n;
      // d/dt [n(t).(p - q(t))] = n'.(p - q) - n.q', q' = omega S (q - pivot)
      r.phi_t = r.n_t.dot(p - q) - r.n.dot(omega * skew() * (q - pivot));
      return r;
    }
    const Vec2 c = pivot + rt * (a - pivot);
    const Vec2 d = p - c;
    const double rho = d.norm();
    r.n = d / rho;
    r.phi = rho - radius;
    r.h = (Mat2::Identity() - r.n * r.n.transpose()) / rho;
    const Vec2 cdot = omega * skew() * (c - pivot);
    r.n_t = -r.h * cdot;
    r.phi_t = -r.n.dot(cdot);
    return r;
  }
  Vec2 velocity(const Vec2& q) const { return omega * skew() * (q - pivot); }
};

/// The impulse of the sdf backend: v' = v - (1 + e) vn n - min(mu jn, |vt|) t + kick n.
inline Vec2 impulse(const Vec2& w, const Vec2& n, const Vec2& u, double e, double mu, double k) {
  const Vec2 vr = w - u;
  const double vn = vr.dot(n);
  const double jn = -(1.0 + e) * vn;
  Vec2 dv = jn * n;
  const Vec2 vt = vr - vn * n;
  const double l = vt.norm();
  if (mu > 0.0 && l > 0.0) dv -= std::min(mu * jn, l) / l * vt;
  return w + dv + k * n;
}

/// One particle's drift over [t0, t0 + h] from (x, v) against `obs`, contact at `offset`
/// (radius + depth_min); `changes` are scheduled velocity changes (tau, dv) applied on the
/// way. Appends the impacts (particle `id`) to `out` if given; returns the end state.
inline void ref_drift(const std::vector<RefObstacle>& obs, double offset, double t0, double h,
                      Vec2& x, Vec2& v, uint32_t id, std::vector<Impact>* out,
                      const std::vector<std::pair<double, Vec2>>& changes = {},
                      const std::vector<std::pair<int64_t, uint8_t>>& change_ids = {}) {
  double tau = 0.0;
  std::size_t next_change = 0;
  int guard = 0;
  while (guard++ < 64) {
    const double seg_end = next_change < changes.size() ? changes[next_change].first : h;
    // the earliest approaching root of g_k(s) = phi_k(x + v (s - tau), t0 + s) - offset
    double best = HUGE_VAL;
    int which = -1;
    for (std::size_t k = 0; k < obs.size(); ++k) {
      auto g = [&](double s) { return obs[k].eval(x + v * (s - tau), t0 + s).phi - offset; };
      const int samples = 4000;
      double s0 = tau, g0 = g(s0);
      for (int q = 1; q <= samples; ++q) {
        const double s1 = tau + (seg_end - tau) * q / samples, g1 = g(s1);
        if (g0 > 0.0 && g1 <= 0.0) {
          double lo = s0, hi = s1;
          for (int it = 0; it < 200 && hi - lo > 0.0; ++it) {
            const double mid = 0.5 * (lo + hi);
            if (mid <= lo || mid >= hi) break;
            (g(mid) > 0.0 ? lo : hi) = mid;
          }
          double s = 0.5 * (lo + hi);
          for (int it = 0; it < 3; ++it) {  // Newton on the bracketed root
            const auto ev = obs[k].eval(x + v * (s - tau), t0 + s);
            const double d = ev.n.dot(v) + ev.phi_t;
            if (d == 0.0) break;
            const double sn = s - (ev.phi - offset) / d;
            if (sn > s0 && sn < s1) s = sn;
          }
          if (s < best) {
            best = s;
            which = static_cast<int>(k);
          }
          break;
        }
        s0 = s1;
        g0 = g1;
      }
    }
    if (which < 0) {  // no impact before the segment's end
      x += v * (seg_end - tau);
      tau = seg_end;
      if (next_change >= changes.size()) return;
      Impact m;
      m.kind = ImpactKind::kChange;
      m.particle = id;
      m.tau = tau;
      m.p = x;
      m.v_before = v;
      v += changes[next_change].second;
      m.v_after = v;
      m.pair = change_ids[next_change].first;
      m.side = change_ids[next_change].second;
      if (out) out->push_back(m);
      ++next_change;
      continue;
    }
    const RefObstacle& o = obs[static_cast<std::size_t>(which)];
    x += v * (best - tau);
    tau = best;
    const auto ev = o.eval(x, t0 + tau);
    const Vec2 pc = x - ev.phi * ev.n;
    const Vec2 u = o.velocity(pc);
    Impact m;
    m.kind = ImpactKind::kToi;
    m.particle = id;
    m.tau = tau;
    m.p = x;
    m.v_before = v;
    m.obstacle = which;
    m.n = ev.n;
    m.n_p = ev.h;
    m.n_t = ev.n_t;
    m.phi = ev.phi;
    m.phi_t = ev.phi_t;
    m.offset = offset;
    m.u = u;
    m.u_p = o.omega * skew();
    m.restitution = o.e;
    m.friction = o.mu;
    m.kick = o.kick;
    m.emitted = true;
    v = impulse(v, ev.n, u, o.e, o.mu, o.kick);
    m.v_after = v;
    if (out) out->push_back(m);
  }
}

/// Discs on linear tracks, the sdf backend's pair schedule (resolve_pairs in
/// backends/sdf/sdf_backend.cpp) for a few discs: every pair's time of impact from the start,
/// handled in time order with the velocities changed by the earlier hits.
struct RefDiscs {
  std::vector<Vec2> x, v;
  std::vector<double> r, w;  ///< radii, inverse masses
  double e = 1.0;
};

inline void ref_pairs(const RefDiscs& d, double h, std::vector<PairHit>& hits,
                      std::vector<std::vector<std::pair<double, Vec2>>>& changes,
                      std::vector<std::vector<std::pair<int64_t, uint8_t>>>& ids) {
  const std::size_t n = d.x.size();
  std::vector<Vec2> xr = d.x, vc(n);
  std::vector<double> tr(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) vc[i] = d.w[i] > 0.0 ? d.v[i] : Vec2::Zero();
  changes.assign(n, {});
  ids.assign(n, {});
  auto toi = [&](std::size_t i, std::size_t j, double tau0, double& tau, bool& touching) {
    const Vec2 pi = xr[i] + vc[i] * (tau0 - tr[i]), pj = xr[j] + vc[j] * (tau0 - tr[j]);
    const Vec2 dx = pi - pj, dv = vc[i] - vc[j];
    const double rr = d.r[i] + d.r[j];
    const double a = dv.squaredNorm(), b = dx.dot(dv), c = dx.squaredNorm() - rr * rr;
    touching = false;
    if (b >= 0.0) return false;
    if (c <= 0.0) {
      tau = tau0;
      touching = true;
      return true;
    }
    const double disc = b * b - a * c;
    if (disc < 0.0) return false;
    tau = tau0 + c / (-b + std::sqrt(disc));
    return tau <= h;
  };
  struct Cand {
    double tau;
    std::size_t i, j;
  };
  std::vector<Cand> cands;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j) {
      double tau = 0.0;
      bool touching = false;
      if (toi(i, j, 0.0, tau, touching)) cands.push_back({tau, i, j});
    }
  std::sort(cands.begin(), cands.end(), [](const Cand& a, const Cand& b) { return a.tau < b.tau; });
  for (const Cand& c : cands) {
    const std::size_t i = c.i, j = c.j;
    double tau = 0.0;
    bool touching = false;
    if (!toi(i, j, std::max(tr[i], tr[j]), tau, touching)) continue;
    PairHit hit;
    hit.i = static_cast<uint32_t>(i);
    hit.j = static_cast<uint32_t>(j);
    hit.tau = tau;
    hit.xr_i = xr[i];
    hit.vc_i = vc[i];
    hit.tr_i = tr[i];
    hit.xr_j = xr[j];
    hit.vc_j = vc[j];
    hit.tr_j = tr[j];
    hit.radius_sum = d.r[i] + d.r[j];
    hit.w_i = d.w[i];
    hit.w_j = d.w[j];
    hit.restitution = d.e;
    hit.touching = touching;
    const Vec2 pi = xr[i] + vc[i] * (tau - tr[i]), pj = xr[j] + vc[j] * (tau - tr[j]);
    const Vec2 nrm = (pi - pj).normalized();
    const double vn = (vc[i] - vc[j]).dot(nrm);
    if (vn >= 0.0) continue;
    const double jn = -(1.0 + d.e) * vn / (d.w[i] + d.w[j]);
    const Vec2 dvi = jn * d.w[i] * nrm, dvj = -jn * d.w[j] * nrm;
    const auto k = static_cast<int64_t>(hits.size());
    hits.push_back(hit);
    xr[i] = pi;
    xr[j] = pj;
    tr[i] = tr[j] = tau;
    vc[i] += dvi;
    vc[j] += dvj;
    if (d.w[i] > 0.0) {
      changes[i].emplace_back(tau, dvi);
      ids[i].emplace_back(k, 0);
    }
    if (d.w[j] > 0.0) {
      changes[j].emplace_back(tau, dvj);
      ids[j].emplace_back(k, 1);
    }
  }
}

}  // namespace pinsim::grad::testing
