// A correct student spring: E = k/2 (R - L)^2 with L the initial length,
// f_a = -k (R - L) R̂ = -f_b (seed, damped spring slide with kd = 0),
// df_a/dx_a = -k [R̂R̂ᵀ + (1 - L/R)(I - R̂R̂ᵀ)].
#pragma once

#include <pinsim/plugin.hpp>
#include <vector>

class StudentSpring {
 public:
  static pinsim::PluginInfo info() {
    pinsim::PluginInfo i;
    i.name = "linear_spring";
    i.doc = "student spring, rest length from the initial configuration";
    i.arity = 2;
    i.capabilities = PINSIM_CAP_INTERNAL;
    i.params.push_back(pinsim::real("k", 10.0).min(0).units("N/m"));
    return i;
  }
  explicit StudentSpring(const pinsim::CreateContext& c) : k_(c.params.real("k")) {
    ends_.assign(c.elements.data, c.elements.data + 2 * c.elements.count);
    for (std::size_t e = 0; e < c.elements.count; ++e)
      rest_.push_back((c.initial.x.col(ends_[2 * e]) - c.initial.x.col(ends_[2 * e + 1])).norm());
  }
  void add_force(const pinsim::StateView& s, pinsim::ForceOut& f) const {
    for (std::size_t e = 0; e < rest_.size(); ++e) {
      const pinsim::Vec2 d = s.x.col(ends_[2 * e]) - s.x.col(ends_[2 * e + 1]);
      const double r = d.norm();
      if (!(r > 0)) continue;  // no direction at zero length
      const pinsim::Vec2 fa = -k_ * (r - rest_[e]) * d / r;
      f.col(ends_[2 * e]) += fa;
      f.col(ends_[2 * e + 1]) -= fa;
    }
  }
  double energy(const pinsim::StateView& s) const {
    double sum = 0;
    for (std::size_t e = 0; e < rest_.size(); ++e) {
      const double c = (s.x.col(ends_[2 * e]) - s.x.col(ends_[2 * e + 1])).norm() - rest_[e];
      sum += 0.5 * k_ * c * c;
    }
    return sum;
  }
  void add_dfdx(const pinsim::StateView& s, pinsim::Triplets& j) const {
    for (std::size_t e = 0; e < rest_.size(); ++e) {
      const pinsim::Vec2 d = s.x.col(ends_[2 * e]) - s.x.col(ends_[2 * e + 1]);
      const double r = d.norm();
      if (!(r > 0)) continue;
      const pinsim::Vec2 n = d / r;
      const pinsim::Mat2 nn = n * n.transpose();
      const pinsim::Mat2 kb = k_ * nn + k_ * (1.0 - rest_[e] / r) * (pinsim::Mat2::Identity() - nn);
      const uint32_t a = ends_[2 * e], b = ends_[2 * e + 1];
      j.add_block(a, a, -kb);
      j.add_block(b, b, -kb);
      j.add_block(a, b, kb);
      j.add_block(b, a, kb);
    }
  }
  void add_dfdv(const pinsim::StateView&, pinsim::Triplets&) const {}

 private:
  double k_;
  std::vector<uint32_t> ends_;
  std::vector<double> rest_;
};
