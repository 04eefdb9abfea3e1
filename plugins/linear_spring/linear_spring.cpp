#include "linear_spring.hpp"

#include <cmath>
#include <string>

namespace pinsim::plugins {

namespace {
/// Below this length the direction R̂ is undefined; a finite-rest-length spring then
/// exerts no force (the zero-rest-length spring needs no direction).
constexpr double kMinLength = 1e-100;
}  // namespace

PluginInfo LinearSpring::info() {
  PluginInfo i;
  i.name = "linear_spring";
  i.version = "1.0.0";
  i.doc =
      "Linear (Hooke) spring between particle pairs, E = k/2 (|p_k - p_l| - L)^2, "
      "f_k = -k (R - L) R̂ = -f_l. rest_length 0 gives the zero-rest-length spring "
      "E = k/2 |p_k - p_l|^2; a negative rest_length (default) takes each element's "
      "initial length.";
  i.arity = 2;
  i.capabilities = PINSIM_CAP_INTERNAL;
  i.params.push_back(real("k", 100.0).min(0).units("N/m").doc("spring stiffness").differentiable());
  i.params.push_back(real("rest_length", -1.0)
                         .units("m")
                         .doc("rest length L; 0: zero-rest-length spring; < 0: each element's "
                              "initial length"));
  return i;
}

LinearSpring::LinearSpring(const CreateContext& ctx) : k_(ctx.params.real("k")) {
  idx_ = element_indices(ctx, 2);
  const double l = ctx.params.real("rest_length");
  rest_.resize(ctx.elements.count);
  for (std::size_t e = 0; e < rest_.size(); ++e)
    rest_[e] =
        l >= 0.0 ? l : (ctx.initial.x.col(idx_[2 * e]) - ctx.initial.x.col(idx_[2 * e + 1])).norm();
  ks_each_.assign(rest_.size(), k_);
  kd_each_.assign(rest_.size(), 0.0);
}

// C = R - L with R = |p_k - p_l|; for L = 0, C = R and ks/2 C^2 = k/2 |p_k - p_l|^2.
void LinearSpring::constraints(const double* x, const uint64_t* which, std::size_t n, double* c,
                               double* dc) const {
  for (std::size_t q = 0; q < n; ++q, dc += 4) {
    if (which[q] >= rest_.size())
      throw Error("constraints: element " + std::to_string(which[q]) + " of " +
                  std::to_string(rest_.size()));
    const auto e = static_cast<std::size_t>(which[q]);
    const uint32_t a = idx_[2 * e], b = idx_[2 * e + 1];
    const double rx = x[2 * a] - x[2 * b], ry = x[2 * a + 1] - x[2 * b + 1];
    const double r = std::sqrt(rx * rx + ry * ry);
    const double inv = r > kMinLength ? 1.0 / r : 0.0;
    c[q] = r - rest_[e];
    dc[0] = rx * inv;
    dc[1] = ry * inv;
    dc[2] = -dc[0];
    dc[3] = -dc[1];
  }
}

void LinearSpring::add_dforce_dparam(const StateView& s, std::string_view param, int,
                                     ForceOut& df) const {
  if (param != "k") throw Error("add_dforce_dparam: no derivative in '" + std::string(param) + "'");
  add_force_with(s, df, 1.0);
}

void LinearSpring::add_force(const StateView& s, ForceOut& f) const { add_force_with(s, f, k_); }

void LinearSpring::add_force_with(const StateView& s, ForceOut& f, double k) const {
  const double* x = s.x.data();
  double* out = f.data();
  const std::size_t m = rest_.size();
  for (std::size_t e = 0; e < m; ++e) {
    const uint32_t a = idx_[2 * e], b = idx_[2 * e + 1];
    const double rx = x[2 * a] - x[2 * b], ry = x[2 * a + 1] - x[2 * b + 1];
    const double l = rest_[e];
    double c = k;  // f_k = -c R with c = k (R - L)/R
    if (l != 0.0) {
      const double r = std::sqrt(rx * rx + ry * ry);
      c = r > kMinLength ? k * (r - l) / r : 0.0;
    }
    out[2 * a] -= c * rx;
    out[2 * a + 1] -= c * ry;
    out[2 * b] += c * rx;
    out[2 * b + 1] += c * ry;
  }
}

double LinearSpring::energy(const StateView& s) const {
  double sum = 0.0;
  for (std::size_t e = 0; e < rest_.size(); ++e) {
    const double d = (s.x.col(idx_[2 * e]) - s.x.col(idx_[2 * e + 1])).norm() - rest_[e];
    sum += d * d;
  }
  return 0.5 * k_ * sum;
}

Mat2 LinearSpring::block(const StateView& s, std::size_t e) const {
  const Vec2 d = s.x.col(idx_[2 * e]) - s.x.col(idx_[2 * e + 1]);
  const double l = rest_[e];
  if (l == 0.0) return k_ * Mat2::Identity();
  const double r = d.norm();
  if (!(r > kMinLength)) return Mat2::Zero();
  const Vec2 n = d / r;
  const Mat2 nn = n * n.transpose();
  return k_ * (nn + (1.0 - l / r) * (Mat2::Identity() - nn));
}

void LinearSpring::add_jacobian_products(const StateView& s, const Field& w, ForceOut& gx,
                                         ForceOut*) const {
  products<false>(s, w, gx, nullptr);
}

void LinearSpring::add_adjoint_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut*,
                                        std::span<double> gp) const {
  if (gp.size() != 1) throw Error("add_adjoint_products: expected 1 slot (k)");
  products<true>(s, w, gx, gp.data());
}

template <bool Params>
void LinearSpring::products(const StateView& s, const Field& w, ForceOut& gx, double* gp) const {
  double dk = 0.0;
  for (std::size_t e = 0; e < rest_.size(); ++e) {
    const uint32_t a = idx_[2 * e], b = idx_[2 * e + 1];
    const Vec2 dw = w.col(a) - w.col(b);
    const Vec2 p = block(s, e) * dw;
    gx.col(a) -= p;
    gx.col(b) += p;
    if constexpr (Params) {  // f_a = -k c R, c = (R - L)/R (1 when L = 0): w.df/dk = -c R.dw
      const Vec2 d = s.x.col(a) - s.x.col(b);
      const double l = rest_[e], r = d.norm();
      const double c = l == 0.0 ? 1.0 : (r > kMinLength ? (r - l) / r : 0.0);
      dk -= c * d.dot(dw);
    }
  }
  if constexpr (Params) gp[0] += dk;
}

void LinearSpring::add_dfdx(const StateView& s, Triplets& J) const {
  for (std::size_t e = 0; e < rest_.size(); ++e) {
    const Mat2 k = block(s, e);
    const uint32_t a = idx_[2 * e], b = idx_[2 * e + 1];
    J.add_block(a, a, -k);
    J.add_block(b, b, -k);
    J.add_block(a, b, k);
    J.add_block(b, a, k);
  }
}

}  // namespace pinsim::plugins

PINSIM_PLUGIN(pinsim::plugins::LinearSpring)
