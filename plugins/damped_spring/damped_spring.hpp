// DampedSpring: f_i = -(δik - δil) R̂ {ks (R - L) + kd Ṙ}, built on the SDK's
// ConstraintSpring with C = R - L (seed, "Damped linear spring with finite rest-length").
#pragma once

#include <pinsim/constraint_spring.hpp>
#include <vector>

namespace pinsim::plugins {

class DampedSpring : public ConstraintSpring<DampedSpring, 2> {
 public:
  static PluginInfo info();
  explicit DampedSpring(const CreateContext& ctx);

  /// C = |p_k - p_l| - L_e, dC/dp_k = R̂, dC/dp_l = -R̂ (R̂ = 0 when the spring has no length).
  double constraint(std::size_t e, const Stencil& p, Stencil& dC) const {
    const double rx = p(0, 0) - p(0, 1), ry = p(1, 0) - p(1, 1);
    const double r = std::sqrt(rx * rx + ry * ry);
    const double inv = r > kMinLength ? 1.0 / r : 0.0;
    dC(0, 0) = rx * inv;
    dC(1, 0) = ry * inv;
    dC(0, 1) = -dC(0, 0);
    dC(1, 1) = -dC(1, 0);
    return r - rest_[e];
  }
  /// d2C/dp_k2 = (I - R̂R̂ᵀ)/R (seed, "Gradient of unit distance vector"); the (k,l) blocks
  /// are its negative. Zero when the spring has no length.
  void constraint_hessian(std::size_t e, const Stencil& p, Hessian& h) const;

  /// Rest length of element e, scene units.
  double rest_length(std::size_t e) const { return rest_[e]; }

  /// Below this length the direction R̂ is undefined and taken as zero.
  static constexpr double kMinLength = 1e-100;

 private:
  std::vector<double> rest_;
};

}  // namespace pinsim::plugins
