#include "damped_spring.hpp"

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

}  // namespace pinsim::plugins

PINSIM_PLUGIN(pinsim::plugins::DampedSpring)
