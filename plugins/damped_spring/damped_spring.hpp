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

  /// Both Jacobians in one pass (replaces the SDK's generic ConstraintSpring::add_jacobians,
  /// which forms the 4x4 Hessian and its products per spring). With n = R̂, B = (I - n nᵀ)/R,
  /// w = ks n + kd B (v_k - v_l) and s = ks (R - L) + kd Ṙ, the generic formula's blocks are
  ///   ∂f/∂x: (k,k) = (l,l) = -n wᵀ - s B,  (k,l) = (l,k) = their negative;
  ///   ∂f/∂v: (k,k) = (l,l) = -kd n nᵀ,     (k,l) = (l,k) = their negative.
  /// The same blocks, in the same order, as the generic pass (so the same pattern); values
  /// equal to rounding (tests/plugins/damped_spring checks both against central differences).
  void add_jacobians(const StateView& s, Triplets* dx, Triplets* dv) const;

  /// gx += (df/dx)^T w, gv += (df/dv)^T w from the same blocks without handing them over:
  /// with d = w_k - w_l, M = -n wᵀ - s B (the (k,k) block), Mᵀ d = -w (n·d) - s B d on p_k and
  /// its negative on p_l; -kd n (n·d) on v_k, its negative on v_l.
  void add_jacobian_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut* gv) const;
  /// The same products and, in the same pass, w . d f / d ks = -sum (n·d)(R - L) into gp[0]
  /// and w . d f / d kd = -sum (n·d) Ṙ into gp[1].
  void add_adjoint_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut* gv,
                            std::span<double> gp) const;

  /// Rest length of element e, scene units.
  double rest_length(std::size_t e) const { return rest_[e]; }

  /// Below this length the direction R̂ is undefined and taken as zero.
  static constexpr double kMinLength = 1e-100;

 private:
  /// The products, with the parameter derivatives' into gp when Params.
  template <bool Params>
  void products(const StateView& s, const Field& w, ForceOut& gx, ForceOut* gv, double* gp) const;
  /// One spring's B = (I - n nᵀ)/R (bxx, bxy, byy), s = ks (R - L) + kd Ṙ and
  /// w = ks n + kd B u: what its df/dx block M = -n wᵀ - s B is made of (add_jacobians and
  /// add_jacobian_products).
  struct Terms {
    double bxx, bxy, byy, sc, wx, wy;
  };
  /// Terms at unit direction n = (ex, ey), 1/R = inv, stretch R - L and relative velocity
  /// u = v_k - v_l = (ux, uy).
  static Terms terms(double ex, double ey, double inv, double stretch, double ux, double uy,
                     double ks, double kd) {
    Terms t;
    t.bxx = (1.0 - ex * ex) * inv;
    t.bxy = -ex * ey * inv;
    t.byy = (1.0 - ey * ey) * inv;
    t.sc = ks * stretch + kd * (ex * ux + ey * uy);
    t.wx = ks * ex + kd * (t.bxx * ux + t.bxy * uy);
    t.wy = ks * ey + kd * (t.bxy * ux + t.byy * uy);
    return t;
  }

  std::vector<double> rest_;
};

}  // namespace pinsim::plugins
