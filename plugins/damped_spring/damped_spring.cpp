#include "damped_spring.hpp"

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
  i.capabilities = PINSIM_CAP_INTERNAL | PINSIM_CAP_DISSIPATIVE;
  i.params.push_back(real("ks", 100.0).min(0).units("N/m").doc("spring stiffness"));
  i.params.push_back(real("kd", 1.0).min(0).units("N s/m").doc("damping along the spring"));
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
  for (std::size_t e = 0; e < count(); ++e) {
    const uint32_t k = particle(e, 0), l = particle(e, 1);
    const double rx = x[2 * k] - x[2 * l], ry = x[2 * k + 1] - x[2 * l + 1];
    const double r = std::sqrt(rx * rx + ry * ry);
    // Zero length: n = 0 and B = 0, so every block is zero (still emitted: same pattern).
    const bool ok = r > kMinLength;
    const double inv = ok ? 1.0 / r : 0.0;
    const double nx = rx * inv, ny = ry * inv;
    if (dx != nullptr) {
      const double ux = v[2 * k] - v[2 * l], uy = v[2 * k + 1] - v[2 * l + 1];
      // B = (I - n nᵀ) / R, symmetric
      const double bxx = (1.0 - nx * nx) * inv, bxy = -nx * ny * inv, byy = (1.0 - ny * ny) * inv;
      const double sc = ks * (r - rest_[e]) + kd * (nx * ux + ny * uy);
      const double wx = ks * nx + kd * (bxx * ux + bxy * uy);
      const double wy = ks * ny + kd * (bxy * ux + byy * uy);
      const double mxx = -nx * wx - sc * bxx, mxy = -nx * wy - sc * bxy;
      const double myx = -ny * wx - sc * bxy, myy = -ny * wy - sc * byy;
      dx->add_block(k, k, mxx, myx, mxy, myy);
      dx->add_block(k, l, -mxx, -myx, -mxy, -myy);
      dx->add_block(l, k, -mxx, -myx, -mxy, -myy);
      dx->add_block(l, l, mxx, myx, mxy, myy);
    }
    if (dv != nullptr) {
      const double dxx = -kd * nx * nx, dxy = -kd * nx * ny, dyy = -kd * ny * ny;
      dv->add_block(k, k, dxx, dxy, dxy, dyy);
      dv->add_block(k, l, -dxx, -dxy, -dxy, -dyy);
      dv->add_block(l, k, -dxx, -dxy, -dxy, -dyy);
      dv->add_block(l, l, dxx, dxy, dxy, dyy);
    }
  }
}

}  // namespace pinsim::plugins

PINSIM_PLUGIN(pinsim::plugins::DampedSpring)
