// Gravity: uniform field f_i = m_i g.
#pragma once

#include <pinsim/plugin.hpp>
#include <vector>

namespace pinsim::plugins {

class Gravity {
 public:
  static PluginInfo info();
  explicit Gravity(const CreateContext& ctx);

  /// f_i += m_i g for every listed particle with finite mass.
  void add_force(const StateView& s, ForceOut& f) const;
  /// E = -sum_i m_i g . x_i
  double energy(const StateView& s) const;
  /// df/dx = 0 and df/dv = 0: a uniform field adds no Jacobian entries.
  void add_dfdx(const StateView&, Triplets&) const {}
  void add_dfdv(const StateView&, Triplets&) const {}

 private:
  Vec2 g_;
  std::vector<uint32_t> particles_;
};

}  // namespace pinsim::plugins
