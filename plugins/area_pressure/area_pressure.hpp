// AreaPressure: keeps the area of each closed ring (a blob's boundary) near its rest area,
// E = k/2 (A - A0)^2 with the shoelace area A, plus an optional damping of dA/dt. A
// whole-body force: each element is one ring of any length (PINSIM_ARITY_VARIABLE).
#pragma once

#include <pinsim/plugin.hpp>
#include <string_view>
#include <vector>

namespace pinsim::plugins {

class AreaPressure {
 public:
  static PluginInfo info();
  explicit AreaPressure(const CreateContext& ctx);

  /// f_i = -(k (A - A0) + kd dA/dt) dA/dp_i on every particle of every ring.
  void add_force(const StateView& s, ForceOut& f) const;
  /// df += d f / d k = -(A - A0) dA/dp_i ("k") or d f / d kd = -dA/dt dA/dp_i ("kd").
  void add_dforce_dparam(const StateView& s, std::string_view param, int, ForceOut& df) const;
  /// E = sum over rings of k/2 (A - A0)^2.
  double energy(const StateView& s) const;
  /// df_i/dp_j = -k g_i g_jᵀ - kd g_i h_jᵀ - (k (A - A0) + kd dA/dt) H_ij (dense per ring).
  void add_dfdx(const StateView& s, Triplets& J) const;
  /// df_i/dv_j = -kd g_i g_jᵀ.
  void add_dfdv(const StateView& s, Triplets& J) const;

  /// The rings as constraints C = A - A0, dC/dp_i = dA/dp_i, ks = k, kd = kd: E = sum k/2 C^2
  /// (pinsim/abi.h, pinsim_constraint_set; each ring listed as its length then its indices).
  ConstraintSet constraint_set() const {
    return {rings(), PINSIM_ARITY_VARIABLE, packed_.data(), ks_each_.data(), kd_each_.data()};
  }
  /// C and dC/dp of the rings listed in `which`, at positions x. Only reads.
  void constraints(const double* x, const uint64_t* which, std::size_t n, double* c,
                   double* dc) const;

  /// Signed rest area A0 of ring e, scene units^2.
  double rest_area(std::size_t e) const { return rest_[e]; }
  /// Signed shoelace area of ring e at positions x (> 0 counter-clockwise).
  double area(const StateView& s, std::size_t e) const;

 private:
  /// The ring's area gradient g_i = dA/dp_i and its rate dA/dt = sum g_i·v_i.
  double gradient(const StateView& s, std::size_t e, std::vector<Vec2>& g) const;
  std::size_t rings() const { return rest_.size(); }
  uint32_t at(std::size_t e, std::size_t k) const { return idx_[start_[e] + k]; }
  std::size_t size(std::size_t e) const { return start_[e + 1] - start_[e]; }

  double k_, kd_;
  std::vector<uint32_t> idx_;              ///< the rings' particles, one ring after another
  std::vector<std::size_t> start_;         ///< ring e is idx_[start_[e] .. start_[e+1])
  std::vector<double> rest_;               ///< A0 per ring
  std::vector<uint32_t> packed_;           ///< per ring its length then its particles
  std::vector<double> ks_each_, kd_each_;  ///< k and kd per ring, for constraint_set()
};

}  // namespace pinsim::plugins
