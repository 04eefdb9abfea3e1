#include "gravity.hpp"

namespace pinsim::plugins {

PluginInfo Gravity::info() {
  PluginInfo i;
  i.name = "gravity";
  i.version = "1.0.0";
  i.doc =
      "Uniform gravity f_i = m_i g on every listed particle (default: all); "
      "pinned particles (inverse mass 0) are skipped.";
  i.arity = 1;
  i.params.push_back(vec2("g", 0.0, -9.81).units("m/s^2").doc("gravitational acceleration"));
  return i;
}

Gravity::Gravity(const CreateContext& ctx) : g_(ctx.params.vec2("g")) {
  particles_.assign(ctx.elements.data, ctx.elements.data + ctx.elements.count);
  for (uint32_t p : particles_)
    if (p >= ctx.initial.n)
      throw Error(ctx.context + ": particle index " + std::to_string(p) + " out of range (" +
                  std::to_string(ctx.initial.n) + " particles)");
}

void Gravity::add_force(const StateView& s, ForceOut& f) const {
  for (uint32_t p : particles_) {
    const double w = s.inv_mass[p];
    if (w > 0.0) f.col(p) += g_ / w;
  }
}

double Gravity::energy(const StateView& s) const {
  double e = 0.0;
  for (uint32_t p : particles_) {
    const double w = s.inv_mass[p];
    if (w > 0.0) e -= g_.dot(s.x.col(p)) / w;
  }
  return e;
}

}  // namespace pinsim::plugins

PINSIM_PLUGIN(pinsim::plugins::Gravity)
