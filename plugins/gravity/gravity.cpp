#include "gravity.hpp"

#include <algorithm>
#include <cmath>
#include <pinsim/parallel.hpp>
#include <string>

namespace pinsim::plugins {

namespace {
/// Pairs closer than this (softened) distance exert no force: coincident unsoftened
/// particles have no defined direction.
constexpr double kMinDist2 = 1e-200;
}  // namespace

template <class F>
void Gravity::for_each_pair(const StateView& s, F&& f) const {
  for (std::size_t a = 0; a < particles_.size(); ++a) {
    const uint32_t k = particles_[a];
    if (!(s.inv_mass[k] > 0.0)) continue;
    for (std::size_t b = a + 1; b < particles_.size(); ++b) {
      const uint32_t l = particles_[b];
      if (!(s.inv_mass[l] > 0.0)) continue;
      const Vec2 r = s.x.col(k) - s.x.col(l);
      const double rs2 = r.squaredNorm() + eps2_;
      if (!(rs2 > kMinDist2)) continue;
      f(k, l, r, rs2);
    }
  }
}

PluginInfo Gravity::info() {
  PluginInfo i;
  i.name = "gravity";
  i.version = "1.1.0";
  i.doc =
      "Gravity on the listed particles (default: all); pinned particles (inverse mass 0) are "
      "skipped. mode 'uniform': f_i = m_i g. mode 'pairwise': every two particles attract "
      "with E = G m_k m_l R_s^alpha / alpha (ln R_s for alpha = 0), R_s = sqrt(R^2 + "
      "softening^2); alpha = -1 is Newtonian gravity.";
  i.arity = 1;
  i.params.push_back(
      string("mode", "uniform").choices("uniform|pairwise").doc("uniform field or pairwise"));
  i.params.push_back(
      vec2("g", 0.0, -9.81).units("m/s^2").doc("uniform: acceleration").differentiable());
  i.params.push_back(real("G", 1.0)
                         .min(0)
                         .units("N m^(2-alpha)/kg^2")
                         .doc("pairwise: coupling constant, |f| = G m_k m_l R^(alpha-1)")
                         .differentiable());
  i.params.push_back(
      real("alpha", -1.0).min(-4).max(4).units("1").doc("pairwise: exponent of R in E"));
  i.params.push_back(
      real("softening", 1e-3).min(0).units("m").doc("pairwise: ε in R_s = sqrt(R^2 + ε^2)"));
  return i;
}

Gravity::Gravity(const CreateContext& ctx)
    : pairwise_(ctx.params.string("mode") == "pairwise"),
      g_(ctx.params.vec2("g")),
      G_(ctx.params.real("G")),
      alpha_(ctx.params.real("alpha")) {
  const double eps = ctx.params.real("softening");
  eps2_ = eps * eps;
  particles_ = element_indices(ctx, 1);
  increasing_ =
      std::adjacent_find(particles_.begin(), particles_.end(),
                         [](uint32_t a, uint32_t b) { return a >= b; }) == particles_.end();
}

void Gravity::add_force(const StateView& s, ForceOut& f) const {
  if (!pairwise_) {
    // Each listed particle's force alone: with every particle listed once (increasing, as
    // "all" gives), in fixed chunks on threads (pinsim/parallel.hpp), the same bits.
    auto add = [&](std::size_t b, std::size_t e) {
      for (std::size_t a = b; a < e; ++a) {
        const uint32_t p = particles_[a];
        const double w = s.inv_mass[p];
        if (w > 0.0) f.col(p) += g_ / w;
      }
    };
    if (!increasing_ || particles_.size() < kParallelItems) {
      add(0, particles_.size());  // a particle listed twice gets g twice, one after the other
      return;
    }
    for_chunks(
        particles_.size(), kParticleChunk,
        [&](std::size_t, std::size_t b, std::size_t e) { add(b, e); }, Schedule::Even);
    return;
  }
  add_pairwise(s, f, G_);
}

void Gravity::add_pairwise(const StateView& s, ForceOut& f, double G) const {
  const double h = 0.5 * (alpha_ - 2.0);
  for_each_pair(s, [&](uint32_t k, uint32_t l, const Vec2& r, double rs2) {
    const Vec2 fk = -G * (1.0 / s.inv_mass[k]) / s.inv_mass[l] * std::pow(rs2, h) * r;
    f.col(k) += fk;
    f.col(l) -= fk;
  });
}

void Gravity::add_dforce_dparam(const StateView& s, std::string_view param, int component,
                                ForceOut& df) const {
  if (param == "g") {  // uniform: d f_i / d g_c = m_i e_c; pairwise: g is not used
    if (pairwise_) return;
    for (const uint32_t p : particles_) {
      const double w = s.inv_mass[p];
      if (w > 0.0) df(component, p) += 1.0 / w;
    }
    return;
  }
  if (param != "G") throw Error("add_dforce_dparam: no derivative in '" + std::string(param) + "'");
  if (pairwise_) add_pairwise(s, df, 1.0);  // linear in G; uniform: G is not used
}

double Gravity::energy(const StateView& s) const {
  double e = 0.0;
  if (!pairwise_) {
    for (uint32_t p : particles_) {
      const double w = s.inv_mass[p];
      if (w > 0.0) e -= g_.dot(s.x.col(p)) / w;
    }
    return e;
  }
  for_each_pair(s, [&](uint32_t k, uint32_t l, const Vec2&, double rs2) {
    const double phi = alpha_ == 0.0 ? 0.5 * std::log(rs2) : std::pow(rs2, 0.5 * alpha_) / alpha_;
    e += G_ / (s.inv_mass[k] * s.inv_mass[l]) * phi;
  });
  return e;
}

void Gravity::add_jacobian_products(const StateView& s, const Field& w, ForceOut& gx,
                                    ForceOut*) const {
  if (pairwise_) pair_products<false>(s, w, gx, nullptr);
}

void Gravity::add_adjoint_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut*,
                                   std::span<double> gp) const {
  if (gp.size() != 3) throw Error("add_adjoint_products: expected 3 slots (g[0], g[1], G)");
  if (pairwise_) {
    pair_products<true>(s, w, gx, &gp[2]);
    return;
  }
  for (const uint32_t p : particles_) {  // uniform: w . d f / d g_c = sum m_i w_c,i
    const double im = s.inv_mass[p];
    if (!(im > 0.0)) continue;
    gp[0] += w(0, p) / im;
    gp[1] += w(1, p) / im;
  }
}

template <bool Params>
void Gravity::pair_products(const StateView& s, const Field& w, ForceOut& gx, double* dG) const {
  double sum = 0.0;
  for_each_pair(s, [&](uint32_t k, uint32_t l, const Vec2& r, double rs2) {
    const double gmm = G_ / (s.inv_mass[k] * s.inv_mass[l]);
    const double p2 = std::pow(rs2, 0.5 * (alpha_ - 2.0));
    const Vec2 d = w.col(k) - w.col(l);
    // K d with K = gmm [p2 I + (alpha - 2) p2 / rs2 r rᵀ]
    const Vec2 kd = gmm * (p2 * d + (alpha_ - 2.0) * p2 / rs2 * r.dot(d) * r);
    gx.col(k) -= kd;
    gx.col(l) += kd;
    // f_k = -G m_k m_l R_s^(alpha - 2) r: w . df/dG = -m_k m_l p2 r.(w_k - w_l)
    if constexpr (Params) sum -= (1.0 / s.inv_mass[k]) / s.inv_mass[l] * p2 * r.dot(d);
  });
  if constexpr (Params) *dG += sum;
}

void Gravity::add_dfdx(const StateView& s, Triplets& J) const {
  if (!pairwise_) return;
  for_each_pair(s, [&](uint32_t k, uint32_t l, const Vec2& r, double rs2) {
    const double gmm = G_ / (s.inv_mass[k] * s.inv_mass[l]);
    const double p2 = std::pow(rs2, 0.5 * (alpha_ - 2.0));
    const Mat2 K = gmm * (p2 * Mat2::Identity() + (alpha_ - 2.0) * p2 / rs2 * r * r.transpose());
    J.add_block(k, k, -K);
    J.add_block(l, l, -K);
    J.add_block(k, l, K);
    J.add_block(l, k, K);
  });
}

}  // namespace pinsim::plugins

PINSIM_PLUGIN(pinsim::plugins::Gravity)
