#include "gradients/drift_adjoint.hpp"

#include <algorithm>
#include <cmath>

namespace pinsim::grad {
namespace {

using Vec8 = Eigen::Matrix<double, 8, 1>;
using Vec11 = Eigen::Matrix<double, 11, 1>;
using Vec9 = Eigen::Matrix<double, 9, 1>;

// One obstacle impact's tangent map (see impact_jacobian in the header): d holds
// (dp', dw', dtau', de, dmu, dk), the result (dp, dw, dtau, dn, dvn).
Vec8 impact_tangent(const Impact& im, double tau_prev, const Vec8& d) {
  const bool toi = im.kind == ImpactKind::kToi;
  const Vec2 w0 = im.v_before;
  const Vec2& n = im.n;
  const double s = im.tau - tau_prev;
  const Vec2 dp0 = d.segment<2>(0), dw0 = d.segment<2>(2);
  const double dtau_prev = d[4], de = d[5], dmu = d[6], dk = d[7];
  // the position at the old time of impact, then the new time of impact
  const Vec2 dq = dp0 + s * dw0 - w0 * dtau_prev;
  const double den = n.dot(w0) + im.phi_t;
  const double dtau = toi && den != 0.0 ? -n.dot(dq) / den : 0.0;
  const Vec2 dp = dq + w0 * dtau;
  const Vec2 dn = im.n_p * dp + im.n_t * dtau;
  // phi stays at the offset along a kToi root; inside the band it moves with p
  const double dphi = toi ? 0.0 : n.dot(dp) + im.phi_t * dtau;
  const Vec2 dpc = dp - dphi * n - im.phi * dn;  // contact point p - phi n
  const Vec2 du = im.u_p * dpc + im.u_t * dtau;
  const Vec2 vr = w0 - im.u, dvr = dw0 - du;
  const double vn = vr.dot(n), dvn = dvr.dot(n) + vr.dot(dn);
  const double e = im.resting ? 0.0 : im.restitution, de_e = im.resting ? 0.0 : de;
  const double k = im.resting ? 0.0 : im.kick, dk_e = im.resting ? 0.0 : dk;
  const double jn = -(1.0 + e) * vn, djn = -(1.0 + e) * dvn - vn * de_e;
  Vec2 ddv = djn * n + jn * dn;
  // Coulomb friction -min(mu jn, |vt|) vt/|vt|: sliding (mu jn < |vt|) or sticking. At
  // mu = 0 the sliding branch gives the right derivative in mu.
  const Vec2 vt = vr - vn * n;
  const double l = vt.norm();
  if (l > 0.0 && (im.friction > 0.0 || dmu != 0.0)) {
    const Vec2 th = vt / l;
    const Vec2 dvt = dvr - dvn * n - vn * dn;
    if (im.friction * jn < l) {
      const Vec2 dth = (dvt - th * th.dot(dvt)) / l;
      ddv -= (dmu * jn + im.friction * djn) * th + im.friction * jn * dth;
    } else {
      ddv -= dvt;
    }
  }
  ddv += dk_e * n + k * dn;
  // the push back to the offset after the impulse, p += (offset - phi) n when below it
  Vec2 dp_out = dp;
  const double push = im.offset - im.phi;
  if (push > 0.0) dp_out += -dphi * n + push * dn;
  Vec8 out;
  out.segment<2>(0) = dp_out;
  out.segment<2>(2) = dw0 + ddv;
  out[4] = dtau;
  out.segment<2>(5) = dn;
  out[7] = dvn;
  return out;
}

// One pair hit's tangent map (see pair_jacobian in the header).
Vec9 pair_tangent(const PairHit& h, const Vec11& d) {
  const Vec2 dxr_i = d.segment<2>(0), dvc_i = d.segment<2>(3);
  const Vec2 dxr_j = d.segment<2>(5), dvc_j = d.segment<2>(8);
  const double dtr_i = d[2], dtr_j = d[7], de = d[10];
  const double a_i = h.tau - h.tr_i, a_j = h.tau - h.tr_j;
  const Vec2 pi = h.xr_i + h.vc_i * a_i, pj = h.xr_j + h.vc_j * a_j;
  const Vec2 dx = pi - pj;
  const double l = dx.norm();
  const Vec2 n = l > 0.0 ? Vec2(dx / l) : Vec2(0.0, 1.0);
  const Vec2 vrel = h.vc_i - h.vc_j;
  const double vn = vrel.dot(n);
  double dtau = 0.0;
  if (h.touching) {
    dtau = h.tr_i >= h.tr_j ? dtr_i : dtr_j;
  } else if (vn != 0.0) {
    // |x_i(tau) - x_j(tau)| = r_i + r_j: n.(d(x_i - x_j) at fixed tau + vrel dtau) = 0
    const Vec2 dd = dxr_i + dvc_i * a_i - h.vc_i * dtr_i - (dxr_j + dvc_j * a_j - h.vc_j * dtr_j);
    dtau = -n.dot(dd) / vn;
  }
  const Vec2 dpi = dxr_i + dvc_i * a_i + h.vc_i * (dtau - dtr_i);
  const Vec2 dpj = dxr_j + dvc_j * a_j + h.vc_j * (dtau - dtr_j);
  const Vec2 dn = l > 0.0 ? Vec2((dpi - dpj - n * n.dot(dpi - dpj)) / l) : Vec2(0.0, 0.0);
  const double dvn = (dvc_i - dvc_j).dot(n) + vrel.dot(dn);
  const double wsum = h.w_i + h.w_j;
  const double jn = -(1.0 + h.restitution) * vn / wsum;
  const double djn = (-(1.0 + h.restitution) * dvn - de * vn) / wsum;
  const Vec2 dj = djn * n + jn * dn;
  Vec9 out;
  out.segment<2>(0) = dpi;
  out.segment<2>(2) = dpj;
  out[4] = dtau;
  out.segment<2>(5) = h.w_i * dj;
  out.segment<2>(7) = -h.w_j * dj;
  return out;
}

}  // namespace

void MaterialGrad::add(int64_t obstacle, double de, double dmu, double dk) {
  if (obstacle < 0) return;
  const auto k = static_cast<std::size_t>(obstacle);
  if (restitution.size() <= k) {
    restitution.resize(k + 1, 0.0);
    friction.resize(k + 1, 0.0);
    kick.resize(k + 1, 0.0);
  }
  restitution[k] += de;
  friction[k] += dmu;
  kick[k] += dk;
}

ImpactJacobian impact_jacobian(const Impact& im, double tau_prev) {
  ImpactJacobian j;
  for (int c = 0; c < 8; ++c) j.col(c) = impact_tangent(im, tau_prev, Vec8::Unit(c));
  return j;
}

PairJacobian pair_jacobian(const PairHit& hit) {
  PairJacobian j;
  for (int c = 0; c < 11; ++c) j.col(c) = pair_tangent(hit, Vec11::Unit(c));
  return j;
}

void drift_adjoint(const DriftTape& tape, Eigen::Matrix2Xd& gx, Eigen::Matrix2Xd& gv,
                   const std::vector<ImpactSeed>* seeds, MaterialGrad& mg) {
  const auto np = static_cast<std::size_t>(tape.x_in.cols());
  if (tape.impacts.empty() && tape.pairs.empty()) {  // x' = x + h v, v' = v for the free
    for (Eigen::Index i = 0; i < static_cast<Eigen::Index>(np); ++i)
      if (tape.inv_mass[i] > 0.0) gv.col(i) += tape.h * gx.col(i);
    return;
  }
  // adjoints of each pair hit's time and velocity changes, per side, from the marches
  std::vector<double> tau_bar(2 * tape.pairs.size(), 0.0);
  std::vector<Vec2> dv_bar(2 * tape.pairs.size(), Vec2::Zero());
  const std::vector<Impact>& im = tape.impacts;
  std::size_t b = 0;
  for (std::size_t i = 0; i < np; ++i) {
    std::size_t e = b;
    while (e < im.size() && im[e].particle == i) ++e;
    const auto col = static_cast<Eigen::Index>(i);
    if (!(tape.inv_mass[col] > 0.0)) {  // pinned: the drift leaves it as it is
      b = e;
      continue;
    }
    // the last segment: x_out = p_m + w_m (h - tau_m), v_out = w_m
    const Vec2 xo = gx.col(col);
    const Vec2 wm = e > b ? im[e - 1].v_after : Vec2(tape.v_in.col(col));
    const double tm = e > b ? im[e - 1].tau : 0.0;
    Vec2 pb = xo, wb = Vec2(gv.col(col)) + (tape.h - tm) * xo;
    double tb = -wm.dot(xo);
    for (std::size_t k = e; k-- > b;) {
      const Impact& m = im[k];
      const double tau_prev = k > b ? im[k - 1].tau : 0.0;
      if (m.kind == ImpactKind::kChange) {
        // p = p' + w' (tau_c - tau'), w = w' + dv_c, tau = tau_c
        const auto slot = 2 * static_cast<std::size_t>(m.pair) + m.side;
        tau_bar[slot] += tb + m.v_before.dot(pb);
        dv_bar[slot] += wb;
        wb += (m.tau - tau_prev) * pb;
        tb = -m.v_before.dot(pb);
        continue;
      }
      Vec8 y;
      y.segment<2>(0) = pb;
      y.segment<2>(2) = wb;
      y[4] = tb;
      y.segment<2>(5).setZero();
      y[7] = 0.0;
      if (seeds) {
        const ImpactSeed& sd = (*seeds)[k];
        y[4] += sd.tau;
        y.segment<2>(5) = sd.n;
        y[7] = sd.vn;
      }
      const Vec8 x = impact_jacobian(m, tau_prev).transpose() * y;
      pb = x.segment<2>(0);
      wb = x.segment<2>(2);
      tb = x[4];
      mg.add(m.obstacle, x[5], x[6], x[7]);
    }
    gx.col(col) = pb;
    gv.col(col) = wb;
    b = e;
  }
  if (tape.pairs.empty()) return;
  // The pair schedule backwards: adjoints of each disc's track (xr, tr, vc).
  Eigen::Matrix2Xd xr_bar = Eigen::Matrix2Xd::Zero(2, tape.x_in.cols());
  Eigen::Matrix2Xd vc_bar = Eigen::Matrix2Xd::Zero(2, tape.x_in.cols());
  Eigen::VectorXd tr_bar = Eigen::VectorXd::Zero(tape.x_in.cols());
  for (std::size_t k = tape.pairs.size(); k-- > 0;) {
    const PairHit& h = tape.pairs[k];
    const auto i = static_cast<Eigen::Index>(h.i), j = static_cast<Eigen::Index>(h.j);
    Vec9 y;
    y.segment<2>(0) = xr_bar.col(i);
    y.segment<2>(2) = xr_bar.col(j);
    y[4] = tr_bar[i] + tr_bar[j] + tau_bar[2 * k] + tau_bar[2 * k + 1];
    y.segment<2>(5) = Vec2(vc_bar.col(i)) + dv_bar[2 * k];
    y.segment<2>(7) = Vec2(vc_bar.col(j)) + dv_bar[2 * k + 1];
    const Vec11 x = pair_jacobian(h).transpose() * y;
    xr_bar.col(i) = x.segment<2>(0);
    tr_bar[i] = x[2];
    vc_bar.col(i) += x.segment<2>(3);
    xr_bar.col(j) = x.segment<2>(5);
    tr_bar[j] = x[7];
    vc_bar.col(j) += x.segment<2>(8);
    mg.pair_restitution += x[10];
  }
  // the tracks start at the drift's input (a pinned disc's velocity counts as 0)
  for (Eigen::Index i = 0; i < tape.x_in.cols(); ++i) {
    gx.col(i) += xr_bar.col(i);
    if (tape.inv_mass[i] > 0.0) gv.col(i) += vc_bar.col(i);
  }
}

void assess_impacts(const DriftTape& tape, std::vector<Finding>& out) {
  for (const Impact& m : tape.impacts) {
    if (m.kind == ImpactKind::kChange) continue;
    const double vn = (m.v_before - m.u).dot(m.n);
    const double scale = m.v_before.norm() + m.u.norm();
    const double t = tape.t0 + m.tau;
    if (m.kind == ImpactKind::kToi && !(-vn > 1e-6 * scale))
      out.push_back({Finding::Kind::kGrazing, m.particle, m.obstacle, t, -vn});
    else if (m.resting || m.kind == ImpactKind::kInBand)
      out.push_back({Finding::Kind::kResting, m.particle, m.obstacle, t, -vn});
  }
}

}  // namespace pinsim::grad
