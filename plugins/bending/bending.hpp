// Bending: hair bending on particle triples (seed, "Hair bending force (flat rest shape)"),
// E = -k/2 â·b̂ with a = p1 - p0, b = p2 - p1, and a rest-angle variant
// E = -k/2 cos(θ - θ0) = -k/2 âᵀ M b̂, M = [[cos θ0, sin θ0], [-sin θ0, cos θ0]].
#pragma once

#include <pinsim/plugin.hpp>
#include <string_view>
#include <vector>

namespace pinsim::plugins {

class Bending {
 public:
  static PluginInfo info();
  explicit Bending(const CreateContext& ctx);

  /// Seed closed form, generalised by M: s = âᵀ M b̂,
  ///   f0 = -k/(2a) (M b̂ - â s),  f2 = k/(2b) (Mᵀ â - b̂ s),  f1 = -f0 - f2.
  void add_force(const StateView& s, ForceOut& f) const;
  /// df += d f / d k: the force at k = 1 (1 / l per triple when length-scaled).
  void add_dforce_dparam(const StateView& s, std::string_view param, int, ForceOut& df) const;
  /// E = -k/2 sum s.
  double energy(const StateView& s) const;
  /// df/dx = k/2 d2s/dp2, from the second derivatives of s in (a, b) (see bending.cpp).
  void add_dfdx(const StateView& s, Triplets& J) const;
  /// No velocity dependence: df/dv = 0.
  void add_dfdv(const StateView&, Triplets&) const {}
  /// gx += (df/dx)^T w = K w (K = k/2 d2s/dp2 is symmetric): with wa = w1 - w0, wb = w2 - w1,
  /// ga = Haa wa + Hab wb and gb = Hba wa + Hbb wb (the second derivatives of s in the edges,
  /// bending.cpp, applied to vectors, no 2x2 block formed), K w = k/2 (-ga, ga - gb, gb).
  void add_jacobian_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut*) const;
  /// The same product and, in the same pass, w . d f / d k into gp[0]: f = k/2 d cos ψ / dp,
  /// so w . df/dk = -1/2 sin ψ (g · D w) per triple (times 1/l when length-scaled).
  void add_adjoint_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut*,
                            std::span<double> gp) const;

  /// The triples as constraints with E = sum ks/2 C^2 + const (pinsim/abi.h,
  /// pinsim_constraint_set): C = √2 sin(φ/2), φ = θ - θ0, since
  /// -k/2 cos φ = k/2 (2 sin²(φ/2)) - k/2; ks = k (per triple when length-scaled), kd = 0.
  ConstraintSet constraint_set() const {
    return {idx_.size() / 3, 3, idx_.data(), ks_each_.data(), kd_each_.data()};
  }
  /// C and dC/dp of the triples listed in `which`, at positions x (see bending.cpp). Only
  /// reads.
  void constraints(const double* x, const uint64_t* which, std::size_t n, double* c,
                   double* dc) const;

  /// Rest angle θ0 of element e, radians (0 for the flat shape).
  double rest_angle(std::size_t e) const;

 private:
  /// The product, with w . df/dk into *gp when Params.
  template <bool Params>
  void products(const StateView& s, const Field& w, ForceOut& gx, double* gp) const;
  /// f += the force with stiffness k (ke[e] per triple when length-scaled).
  void add_force_with(const StateView& s, ForceOut& f, double k, const double* ke) const;
  template <bool Flat, bool Scaled>
  void add_force_impl(const StateView& s, ForceOut& f, double k, const double* ke) const;
  /// Stiffness of element e: k, or k / (mean initial edge length) when length-scaled.
  double k_of(std::size_t e) const { return ke_.empty() ? k_ : ke_[e]; }

  double k_;
  bool flat_ = true;                       ///< every θ0 is 0: the seed's formula, no M
  std::vector<uint32_t> idx_;              ///< 3 per element
  std::vector<double> c0_;                 ///< cos θ0 per element (empty when flat)
  std::vector<double> s0_;                 ///< sin θ0 per element (empty when flat)
  std::vector<double> ke_;                 ///< per-element stiffness when length-scaled, else empty
  std::vector<double> dke_;                ///< d ke / d k = 1 / l per element (length-scaled)
  std::vector<double> ks_each_, kd_each_;  ///< stiffness and 0 per element, for constraint_set()
};

}  // namespace pinsim::plugins
