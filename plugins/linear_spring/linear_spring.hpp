// LinearSpring: Hooke springs between particle pairs, zero or finite rest length
// (seed, "Zero rest-length spring between two particles" and "Linear spring with finite
// rest-length, L").
#pragma once

#include <pinsim/plugin.hpp>
#include <string_view>
#include <vector>

namespace pinsim::plugins {

class LinearSpring {
 public:
  static PluginInfo info();
  explicit LinearSpring(const CreateContext& ctx);

  /// f_k = -k (R - L) R̂ = -f_l; with L = 0 exactly f_k = -k (p_k - p_l).
  void add_force(const StateView& s, ForceOut& f) const;
  /// df += d f / d k = -(R - L) R̂ on p_k, (R - L) R̂ on p_l (the force at k = 1).
  void add_dforce_dparam(const StateView& s, std::string_view param, int, ForceOut& df) const;
  /// E = sum k/2 (R - L)^2.
  double energy(const StateView& s) const;
  /// df_k/dp_k = -K with K = k [R̂R̂ᵀ + (1 - L/R)(I - R̂R̂ᵀ)]; (k,l) blocks +K.
  void add_dfdx(const StateView& s, Triplets& J) const;
  /// No velocity dependence: df/dv = 0.
  void add_dfdv(const StateView&, Triplets&) const {}
  /// gx += (df/dx)^T w: K symmetric, so -K (w_k - w_l) on p_k and its negative on p_l; gv: 0.
  void add_jacobian_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut*) const;
  /// The same products and, in their pass, w . d f / d k = -sum c R·(w_a - w_b) into gp[0]
  /// (c = (R - L)/R, 1 when L = 0).
  void add_adjoint_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut*,
                            std::span<double> gp) const;

  /// The springs as constraints C = R - L, dC/dp_k = R̂ = -dC/dp_l (R̂ = 0 at R = 0), with
  /// ks = k, kd = 0: E = sum k/2 C^2 (pinsim/abi.h, pinsim_constraint_set).
  ConstraintSet constraint_set() const {
    return {rest_.size(), 2, idx_.data(), ks_each_.data(), kd_each_.data()};
  }
  /// C and dC/dp of the springs listed in `which`, at positions x. Only reads.
  void constraints(const double* x, const uint64_t* which, std::size_t n, double* c,
                   double* dc) const;

  double rest_length(std::size_t e) const { return rest_[e]; }

 private:
  /// The products, with w . df/dk into *gp when Params.
  template <bool Params>
  void products(const StateView& s, const Field& w, ForceOut& gx, double* gp) const;
  /// f += the springs' force with stiffness k.
  void add_force_with(const StateView& s, ForceOut& f, double k) const;
  /// 2x2 stiffness block K of element e at positions x.
  Mat2 block(const StateView& s, std::size_t e) const;

  double k_;
  std::vector<uint32_t> idx_;              ///< 2 per element
  std::vector<double> rest_;               ///< L per element
  std::vector<double> ks_each_, kd_each_;  ///< k and 0 per element, for constraint_set()
};

}  // namespace pinsim::plugins
