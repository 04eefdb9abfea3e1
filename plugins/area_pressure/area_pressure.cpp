#include "area_pressure.hpp"

#include <cmath>
#include <string>

namespace pinsim::plugins {

namespace {

/// Rotation by -90 degrees: R (a, b) = (b, -a).
Mat2 rot() {
  Mat2 r;
  r << 0.0, 1.0, -1.0, 0.0;
  return r;
}

}  // namespace

PluginInfo AreaPressure::info() {
  PluginInfo i;
  i.name = "area_pressure";
  i.version = "1.0.0";
  i.doc =
      "Area preservation (pressure) on closed rings, e.g. a blob's 'boundary' set: "
      "E = k/2 (A - A0)^2 with the shoelace area A = 1/2 sum (x_i y_i+1 - x_i+1 y_i), "
      "f_i = -(k (A - A0) + kd dA/dt) dA/dp_i. Each element is one whole ring of any length "
      "(>= 3 particles, the last joined to the first). A0 is each ring's initial area "
      "(rest 'initial') or rest_area with the ring's initial orientation (rest 'value').";
  i.arity = PINSIM_ARITY_VARIABLE;
  i.capabilities = PINSIM_CAP_INTERNAL | PINSIM_CAP_DISSIPATIVE;
  i.params.push_back(real("k", 1000.0)
                         .min(0)
                         .units("J/m^4")
                         .doc("area stiffness, E = k/2 (A - A0)^2 (scene units m)")
                         .differentiable());
  i.params.push_back(real("kd", 0.0)
                         .min(0)
                         .units("J s/m^4")
                         .doc("damping of the area rate: adds -kd dA/dt dA/dp_i")
                         .differentiable());
  i.params.push_back(string("rest", "initial")
                         .choices("initial|value")
                         .doc("rest area: each ring's initial area, or rest_area"));
  i.params.push_back(
      real("rest_area", 0.0)
          .min(0)
          .units("m^2")
          .doc("|A0| when rest is 'value'; the sign follows the ring's initial orientation"));
  return i;
}

AreaPressure::AreaPressure(const CreateContext& ctx)
    : k_(ctx.params.real("k")), kd_(ctx.params.real("kd")) {
  const Elements& el = ctx.elements;
  if (el.arity != PINSIM_ARITY_VARIABLE)
    throw Error(ctx.context +
                ": area_pressure elements are whole rings (variable length), got "
                "arity " +
                std::to_string(el.arity));
  start_.push_back(0);
  for (std::size_t e = 0; e < el.count; ++e) {
    const std::size_t m = el.size(e);
    if (m < 3)
      throw Error(ctx.context + ": element " + std::to_string(e) + " has " + std::to_string(m) +
                  " particle(s); an area needs a closed ring of at least 3 (use a body's "
                  "'boundary' set)");
    for (std::size_t k = 0; k < m; ++k) {
      const uint32_t p = el(e, k);
      if (p >= ctx.initial.n)
        throw Error(ctx.context + ": element " + std::to_string(e) + ": particle index " +
                    std::to_string(p) + " out of range (" + std::to_string(ctx.initial.n) +
                    " particles)");
      idx_.push_back(p);
    }
    start_.push_back(idx_.size());
  }
  rest_.assign(start_.size() - 1, 0.0);
  const bool initial = ctx.params.string("rest") == "initial";
  const double a_abs = ctx.params.real("rest_area");
  for (std::size_t e = 0; e < rings(); ++e) {
    const double a0 = area(ctx.initial, e);
    rest_[e] = initial ? a0 : (a0 < 0.0 ? -a_abs : a_abs);
    packed_.push_back(static_cast<uint32_t>(size(e)));
    for (std::size_t k = 0; k < size(e); ++k) packed_.push_back(at(e, k));
  }
  ks_each_.assign(rings(), k_);
  kd_each_.assign(rings(), kd_);
}

// C = A - A0 by the shoelace sum, dC/dp_i = g_i = 1/2 R (p_{i+1} - p_{i-1}) (see gradient()).
void AreaPressure::constraints(const double* x, const uint64_t* which, std::size_t n, double* c,
                               double* dc) const {
  for (std::size_t q = 0; q < n; ++q) {
    if (which[q] >= rings())
      throw Error("constraints: element " + std::to_string(which[q]) + " of " +
                  std::to_string(rings()));
    const auto e = static_cast<std::size_t>(which[q]);
    const std::size_t m = size(e);
    double a = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      const uint32_t p = at(e, i), nx = at(e, (i + 1) % m), pv = at(e, (i + m - 1) % m);
      a += x[2 * p] * x[2 * nx + 1] - x[2 * nx] * x[2 * p + 1];
      dc[2 * i] = 0.5 * (x[2 * nx + 1] - x[2 * pv + 1]);
      dc[2 * i + 1] = 0.5 * (x[2 * pv] - x[2 * nx]);
    }
    c[q] = 0.5 * a - rest_[e];
    dc += 2 * m;
  }
}

// Shoelace: A = 1/2 sum_i (x_i y_{i+1} - x_{i+1} y_i), indices mod m; > 0 for a
// counter-clockwise ring, and unchanged by translation (the sum telescopes) and rotation.
double AreaPressure::area(const StateView& s, std::size_t e) const {
  const std::size_t m = size(e);
  double a = 0.0;
  for (std::size_t i = 0; i < m; ++i) {
    const auto p = s.x.col(at(e, i)), q = s.x.col(at(e, (i + 1) % m));
    a += p.x() * q.y() - q.x() * p.y();
  }
  return 0.5 * a;
}

// Only the two terms with p_i depend on it:
//   dA/dx_i = 1/2 (y_{i+1} - y_{i-1}),  dA/dy_i = 1/2 (x_{i-1} - x_{i+1}),
// i.e. g_i = 1/2 R (p_{i+1} - p_{i-1}) with R (a, b) = (b, -a); dA/dt = sum_i g_i·v_i.
double AreaPressure::gradient(const StateView& s, std::size_t e, std::vector<Vec2>& g) const {
  const std::size_t m = size(e);
  g.resize(m);
  double rate = 0.0;
  for (std::size_t i = 0; i < m; ++i) {
    const auto next = s.x.col(at(e, (i + 1) % m)), prev = s.x.col(at(e, (i + m - 1) % m));
    g[i] = 0.5 * Vec2(next.y() - prev.y(), prev.x() - next.x());
    rate += g[i].dot(s.v.col(at(e, i)));
  }
  return rate;
}

void AreaPressure::add_dforce_dparam(const StateView& s, std::string_view param, int,
                                     ForceOut& df) const {
  const bool stiffness = param == "k";
  if (!stiffness && param != "kd")
    throw Error("add_dforce_dparam: no derivative in '" + std::string(param) + "'");
  std::vector<Vec2> g;
  for (std::size_t e = 0; e < rings(); ++e) {
    const double rate = gradient(s, e, g);
    const double p = stiffness ? area(s, e) - rest_[e] : rate;
    for (std::size_t i = 0; i < g.size(); ++i) df.col(at(e, i)) -= p * g[i];
  }
}

void AreaPressure::add_force(const StateView& s, ForceOut& f) const {
  std::vector<Vec2> g;
  for (std::size_t e = 0; e < rings(); ++e) {
    const double rate = gradient(s, e, g);
    const double p = k_ * (area(s, e) - rest_[e]) + kd_ * rate;  // the ring's "pressure"
    for (std::size_t i = 0; i < g.size(); ++i) f.col(at(e, i)) -= p * g[i];
  }
}

double AreaPressure::energy(const StateView& s) const {
  double E = 0.0;
  for (std::size_t e = 0; e < rings(); ++e) {
    const double c = area(s, e) - rest_[e];
    E += 0.5 * k_ * c * c;
  }
  return E;
}

// f_i = -P g_i with P = k (A - A0) + kd dA/dt. Differentiating:
//   df_i/dp_j = -g_i (dP/dp_j)ᵀ - P dg_i/dp_j,  dP/dp_j = k g_j + kd h_j,
// where the Hessian of A has only dg_i/dp_{i+1} = R/2 and dg_i/dp_{i-1} = -R/2, and
// h_j = d(dA/dt)/dp_j = sum_m (dg_m/dp_j)ᵀ v_m = 1/2 R (v_{j+1} - v_{j-1}) (Rᵀ = -R).
// The g gᵀ term couples every pair of a ring's particles: the Jacobian is dense per ring.
void AreaPressure::add_dfdx(const StateView& s, Triplets& J) const {
  const Mat2 r = rot();
  std::vector<Vec2> g;
  for (std::size_t e = 0; e < rings(); ++e) {
    const std::size_t m = size(e);
    const double rate = gradient(s, e, g);
    const double p = k_ * (area(s, e) - rest_[e]) + kd_ * rate;
    std::vector<Vec2> dp(m);  // dP/dp_j
    for (std::size_t j = 0; j < m; ++j) {
      const Vec2 h = 0.5 * r * (s.v.col(at(e, (j + 1) % m)) - s.v.col(at(e, (j + m - 1) % m)));
      dp[j] = k_ * g[j] + kd_ * h;
    }
    for (std::size_t i = 0; i < m; ++i) {
      for (std::size_t j = 0; j < m; ++j)
        J.add_block(at(e, i), at(e, j), -g[i] * dp[j].transpose());
      J.add_block(at(e, i), at(e, (i + 1) % m), -0.5 * p * r);
      J.add_block(at(e, i), at(e, (i + m - 1) % m), 0.5 * p * r);
    }
  }
}

void AreaPressure::add_dfdv(const StateView& s, Triplets& J) const {
  if (kd_ == 0.0) return;
  std::vector<Vec2> g;
  for (std::size_t e = 0; e < rings(); ++e) {
    gradient(s, e, g);
    for (std::size_t i = 0; i < g.size(); ++i)
      for (std::size_t j = 0; j < g.size(); ++j)
        J.add_block(at(e, i), at(e, j), -kd_ * g[i] * g[j].transpose());
  }
}

}  // namespace pinsim::plugins

PINSIM_PLUGIN(pinsim::plugins::AreaPressure)
