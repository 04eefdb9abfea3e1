#include "damped_spring.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace pinsim::plugins {

PluginInfo DampedSpring::info() {
  PluginInfo i;
  i.name = "damped_spring";
  i.version = "1.0.0";
  i.doc =
      "Damped linear spring between particle pairs: f_k = -R̂ {ks (R - L) + kd Ṙ}, f_l = -f_k, "
      "Ṙ = (v_k - v_l)·R̂. Rest length L defaults to the initial distance. Built on "
      "pinsim/constraint_spring.hpp with C = R - L.";
  i.arity = 2;
  // Concurrent: an instance keeps its scratch in itself (ConstraintSpring's add_force plan),
  // nothing static; two instances may run at once.
  i.capabilities = PINSIM_CAP_INTERNAL | PINSIM_CAP_DISSIPATIVE | PINSIM_CAP_CONCURRENT;
  // ks and kd: their derivatives from ConstraintSpring::add_dforce_dparam
  i.params.push_back(
      real("ks", 100.0).min(0).units("N/m").doc("spring stiffness").differentiable());
  i.params.push_back(
      real("kd", 1.0).min(0).units("N s/m").doc("damping along the spring").differentiable());
  i.params.push_back(real("rest_length", -1.0)
                         .units("m")
                         .doc("rest length L for every element; < 0: each element's initial "
                              "length"));
  return i;
}

DampedSpring::DampedSpring(const CreateContext& ctx)
    : ConstraintSpring(ctx, ctx.params.real("ks"), ctx.params.real("kd")) {
  const double l = ctx.params.real("rest_length");
  rest_.resize(count());
  for (std::size_t e = 0; e < count(); ++e)
    rest_[e] = l >= 0.0
                   ? l
                   : (ctx.initial.x.col(particle(e, 0)) - ctx.initial.x.col(particle(e, 1))).norm();
}

void DampedSpring::constraint_hessian(std::size_t, const Stencil& p, Hessian& h) const {
  const Vec2 d = p.col(0) - p.col(1);
  const double r = d.norm();
  if (!(r > kMinLength)) {
    h.setZero();
    return;
  }
  const double inv = 1.0 / r;
  const Vec2 n = d * inv;
  const Mat2 b = (Mat2::Identity() - n * n.transpose()) * inv;
  h.block<2, 2>(0, 0) = b;
  h.block<2, 2>(2, 2) = b;
  h.block<2, 2>(0, 2) = -b;
  h.block<2, 2>(2, 0) = -b;
}

void DampedSpring::add_jacobians(const StateView& s, Triplets* dx, Triplets* dv) const {
  if (dv != nullptr && kd() == 0.0) dv = nullptr;
  if (dx == nullptr && dv == nullptr) return;
  const double* x = s.x.data();
  const double* v = s.v.data();
  const double ks = this->ks(), kd = this->kd();
  // Springs in groups: first each one's length and direction (a square root and a division
  // apiece, independent from spring to spring: a short loop lets the processor overlap
  // them), then the blocks.
  constexpr std::size_t kGroup = 32;
  double len[kGroup], inv[kGroup], nx[kGroup], ny[kGroup];
  const std::size_t m = count();
  for (std::size_t g = 0; g < m; g += kGroup) {
    const std::size_t size = std::min(kGroup, m - g);
    for (std::size_t q = 0; q < size; ++q) {
      const uint32_t k = particle(g + q, 0), l = particle(g + q, 1);
      const double rx = x[2 * k] - x[2 * l], ry = x[2 * k + 1] - x[2 * l + 1];
      const double r = std::sqrt(rx * rx + ry * ry);
      // Zero length: n = 0 and B = 0, so every block is zero (still emitted: same pattern).
      const double i = r > kMinLength ? 1.0 / r : 0.0;
      len[q] = r;
      inv[q] = i;
      nx[q] = rx * i;
      ny[q] = ry * i;
    }
    for (std::size_t q = 0; q < size; ++q) {
      const std::size_t e = g + q;
      const uint32_t k = particle(e, 0), l = particle(e, 1);
      const double ex = nx[q], ey = ny[q];
      if (dx != nullptr) {
        const Terms t = terms(ex, ey, inv[q], len[q] - rest_[e], v[2 * k] - v[2 * l],
                              v[2 * k + 1] - v[2 * l + 1], ks, kd);
        const double mxx = -ex * t.wx - t.sc * t.bxx, mxy = -ex * t.wy - t.sc * t.bxy;
        const double myx = -ey * t.wx - t.sc * t.bxy, myy = -ey * t.wy - t.sc * t.byy;
        dx->add_block(k, k, mxx, myx, mxy, myy);
        dx->add_block(k, l, -mxx, -myx, -mxy, -myy);
        dx->add_block(l, k, -mxx, -myx, -mxy, -myy);
        dx->add_block(l, l, mxx, myx, mxy, myy);
      }
      if (dv != nullptr) {
        const double dxx = -kd * ex * ex, dxy = -kd * ex * ey, dyy = -kd * ey * ey;
        dv->add_block(k, k, dxx, dxy, dxy, dyy);
        dv->add_block(k, l, -dxx, -dxy, -dxy, -dyy);
        dv->add_block(l, k, -dxx, -dxy, -dxy, -dyy);
        dv->add_block(l, l, dxx, dxy, dxy, dyy);
      }
    }
  }
}

void DampedSpring::add_jacobian_products(const StateView& s, const Field& w, ForceOut& gx,
                                         ForceOut* gv) const {
  products<false>(s, w, gx, gv, nullptr);
}

void DampedSpring::add_adjoint_products(const StateView& s, const Field& w, ForceOut& gx,
                                        ForceOut* gv, std::span<double> gp) const {
  if (gp.size() != 2) throw Error("add_adjoint_products: expected 2 slots (ks, kd)");
  products<true>(s, w, gx, gv, gp.data());
}

template <bool Params>
void DampedSpring::products(const StateView& s, const Field& wt, ForceOut& gx, ForceOut* gv,
                            double* gp) const {
  if (gv != nullptr && kd() == 0.0) gv = nullptr;
  double dks = 0.0, dkd = 0.0;
  const double* x = s.x.data();
  const double* v = s.v.data();
  const double* w = wt.data();
  double* ox = gx.data();
  double* ov = gv != nullptr ? gv->data() : nullptr;
  const double ks = this->ks(), kd = this->kd();
  for (std::size_t e = 0; e < count(); ++e) {
    const uint32_t k = particle(e, 0), l = particle(e, 1);
    const double rx = x[2 * k] - x[2 * l], ry = x[2 * k + 1] - x[2 * l + 1];
    const double r = std::sqrt(rx * rx + ry * ry);
    const double i = r > kMinLength ? 1.0 / r : 0.0;  // zero length: every block is zero
    const double ex = rx * i, ey = ry * i;
    const double dx = w[2 * k] - w[2 * l], dy = w[2 * k + 1] - w[2 * l + 1];
    const Terms t = terms(ex, ey, i, r - rest_length(e), v[2 * k] - v[2 * l],
                          v[2 * k + 1] - v[2 * l + 1], ks, kd);
    const double nd = ex * dx + ey * dy;
    if constexpr (Params) {  // f_k = -n (ks (R - L) + kd Ṙ): w.df/dks = -(n·d)(R - L), etc.
      dks -= nd * (r - rest_length(e));
      dkd -= nd * (ex * (v[2 * k] - v[2 * l]) + ey * (v[2 * k + 1] - v[2 * l + 1]));
    }
    const double px = -t.wx * nd - t.sc * (t.bxx * dx + t.bxy * dy);
    const double py = -t.wy * nd - t.sc * (t.bxy * dx + t.byy * dy);
    ox[2 * k] += px;
    ox[2 * k + 1] += py;
    ox[2 * l] -= px;
    ox[2 * l + 1] -= py;
    if (ov != nullptr) {
      const double qx = -kd * ex * nd, qy = -kd * ey * nd;
      ov[2 * k] += qx;
      ov[2 * k + 1] += qy;
      ov[2 * l] -= qx;
      ov[2 * l + 1] -= qy;
    }
  }
  if constexpr (Params) {
    gp[0] += dks;
    gp[1] += dkd;
  }
}

}  // namespace pinsim::plugins

PINSIM_PLUGIN(pinsim::plugins::DampedSpring)
