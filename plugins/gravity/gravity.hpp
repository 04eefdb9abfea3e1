// Gravity: a uniform field f_i = m_i g (default), or pairwise attraction between every two
// listed particles with energy G m_k m_l R_s^α / α (seed, "Gradient of distance to power α
// (e.g., gravity, bending)"), R_s = sqrt(R² + ε²) the softened distance.
#pragma once

#include <pinsim/plugin.hpp>
#include <string_view>
#include <vector>

namespace pinsim::plugins {

class Gravity {
 public:
  static PluginInfo info();
  explicit Gravity(const CreateContext& ctx);

  /// uniform: f_i += m_i g. pairwise: f_k += -G m_k m_l R_s^(α-2) (p_k - p_l), f_l = -f_k.
  void add_force(const StateView& s, ForceOut& f) const;
  /// df += d f / d g_c (uniform: m_i e_c on each listed particle) or d f / d G (pairwise:
  /// the force at G = 1); 0 for the parameter the mode does not use.
  void add_dforce_dparam(const StateView& s, std::string_view param, int component,
                         ForceOut& df) const;
  /// uniform: E = -Σ m_i g·x_i. pairwise: E = Σ_{k<l} G m_k m_l φ(R_s),
  /// φ = R_s^α / α (α ≠ 0, α = -1 is Newton's -G m m / R), φ = ln R_s (α = 0).
  double energy(const StateView& s) const;
  /// uniform: 0. pairwise: df_k/dp_k = -K, df_k/dp_l = K with
  /// K = G m_k m_l [R_s^(α-2) I + (α-2) R_s^(α-4) R Rᵀ].
  void add_dfdx(const StateView& s, Triplets& J) const;
  /// No velocity dependence: df/dv = 0.
  void add_dfdv(const StateView&, Triplets&) const {}
  /// gx += (df/dx)^T w: uniform 0; pairwise, K symmetric, -K (w_k - w_l) on p_k and its
  /// negative on p_l. gv: 0.
  void add_jacobian_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut*) const;
  /// The same products and, in their pass, w . d f / d g_c = Σ m_i w_c,i (uniform) into
  /// gp[0], gp[1] and w . d f / d G (pairwise: w . the force at G = 1) into gp[2].
  void add_adjoint_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut*,
                            std::span<double> gp) const;

 private:
  /// pairwise: the products, with w . df/dG added to *dG when Params.
  template <bool Params>
  void pair_products(const StateView& s, const Field& w, ForceOut& gx, double* dG) const;
  /// Calls f(k, l, r, rs2) for every pair k < l (in list order) of listed particles with
  /// inverse mass > 0 whose softened squared distance rs2 = |r|² + ε² (r = p_k - p_l) is
  /// above the degenerate limit: the one pair loop of the pairwise mode.
  template <class F>
  void for_each_pair(const StateView& s, F&& f) const;
  /// pairwise: f += the attraction with coupling constant G.
  void add_pairwise(const StateView& s, ForceOut& f, double G) const;

  bool pairwise_ = false;
  Vec2 g_;
  double G_ = 1.0;
  double alpha_ = -1.0;
  double eps2_ = 0.0;  ///< softening squared
  std::vector<uint32_t> particles_;
  bool increasing_ = false;  ///< each particle listed once, in increasing order
};

}  // namespace pinsim::plugins
