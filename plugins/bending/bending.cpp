#include "bending.hpp"

#include <cmath>
#include <string>

namespace pinsim::plugins {

namespace {
/// Below this edge length the edge direction is undefined: the triple exerts no force.
constexpr double kMinLength = 1e-100;
}  // namespace

PluginInfo Bending::info() {
  PluginInfo i;
  i.name = "bending";
  i.version = "1.0.0";
  i.doc =
      "Hair bending on particle triples (p0, p1, p2): E = -k/2 cos(θ - θ0), θ the signed "
      "angle from a = p1 - p0 to b = p2 - p1. shape 'flat' is the seed's E = -k/2 â·b̂ "
      "(θ0 = 0); 'initial' takes each triple's initial angle; 'angle' uses rest_angle.";
  i.arity = 3;
  i.capabilities = PINSIM_CAP_INTERNAL;
  i.params.push_back(
      real("k", 1.0).min(0).units("J").doc("bending stiffness, E = -k/2 cos θ").differentiable());
  i.params.push_back(
      string("shape", "flat").choices("flat|initial|angle").doc("rest shape of every triple"));
  i.params.push_back(
      real("rest_angle", 0.0).units("rad").doc("rest angle θ0 when shape is 'angle'"));
  i.params.push_back(boolean("length_scaled", false)
                         .doc("stiffness k / l per triple, l its mean initial edge length "
                              "(k then in J m)"));
  return i;
}

Bending::Bending(const CreateContext& ctx) : k_(ctx.params.real("k")) {
  idx_ = element_indices(ctx, 3);
  if (ctx.params.boolean("length_scaled")) {
    // Discrete rod bending stiffness ~ EI / l (seed, "Length-dependent bending stiffness",
    // Kass): each triple's k divided by its mean initial edge length; 0 if that is 0.
    ke_.resize(ctx.elements.count);
    dke_.resize(ctx.elements.count);
    for (std::size_t e = 0; e < ke_.size(); ++e) {
      const double la =
          (ctx.initial.x.col(idx_[3 * e + 1]) - ctx.initial.x.col(idx_[3 * e])).norm();
      const double lb =
          (ctx.initial.x.col(idx_[3 * e + 2]) - ctx.initial.x.col(idx_[3 * e + 1])).norm();
      const double l = 0.5 * (la + lb);
      ke_[e] = l > kMinLength ? k_ / l : 0.0;
      dke_[e] = l > kMinLength ? 1.0 / l : 0.0;
    }
  }
  ks_each_.resize(ctx.elements.count);
  for (std::size_t e = 0; e < ks_each_.size(); ++e) ks_each_[e] = k_of(e);
  kd_each_.assign(ctx.elements.count, 0.0);
  const std::string shape = ctx.params.string("shape");
  if (shape == "flat") return;
  flat_ = false;
  const std::size_t m = ctx.elements.count;
  c0_.resize(m);
  s0_.resize(m);
  const double th = ctx.params.real("rest_angle");
  for (std::size_t e = 0; e < m; ++e) {
    if (shape == "angle") {
      c0_[e] = std::cos(th);
      s0_[e] = std::sin(th);
      continue;
    }
    const Vec2 a = ctx.initial.x.col(idx_[3 * e + 1]) - ctx.initial.x.col(idx_[3 * e]);
    const Vec2 b = ctx.initial.x.col(idx_[3 * e + 2]) - ctx.initial.x.col(idx_[3 * e + 1]);
    const double la = a.norm(), lb = b.norm();
    if (la > kMinLength && lb > kMinLength) {  // degenerate initial triple: flat
      c0_[e] = a.dot(b) / (la * lb);
      s0_[e] = (a.x() * b.y() - a.y() * b.x()) / (la * lb);
    } else {
      c0_[e] = 1.0;
      s0_[e] = 0.0;
    }
  }
}

double Bending::rest_angle(std::size_t e) const { return flat_ ? 0.0 : std::atan2(s0_[e], c0_[e]); }

template <bool Flat, bool Scaled>
void Bending::add_force_impl(const StateView& s, ForceOut& f, double k, const double* ke) const {
  const double* x = s.x.data();
  double* out = f.data();
  const std::size_t m = idx_.size() / 3;
  const uint32_t* id = idx_.data();
  for (std::size_t e = 0; e < m; ++e, id += 3) {
    const double hk = 0.5 * (Scaled ? ke[e] : k);
    const uint32_t i0 = id[0], i1 = id[1], i2 = id[2];
    const double ax = x[2 * i1] - x[2 * i0], ay = x[2 * i1 + 1] - x[2 * i0 + 1];
    const double bx = x[2 * i2] - x[2 * i1], by = x[2 * i2 + 1] - x[2 * i1 + 1];
    const double la = std::sqrt(ax * ax + ay * ay), lb = std::sqrt(bx * bx + by * by);
    if (!(la > kMinLength && lb > kMinLength)) continue;
    const double ia = 1.0 / la, ib = 1.0 / lb;
    const double ahx = ax * ia, ahy = ay * ia, bhx = bx * ib, bhy = by * ib;
    double mx = bhx, my = bhy, nx = ahx, ny = ahy;  // m = M b̂, n = Mᵀ â
    if constexpr (!Flat) {
      const double c = c0_[e], sn = s0_[e];
      mx = c * bhx + sn * bhy;
      my = -sn * bhx + c * bhy;
      nx = c * ahx - sn * ahy;
      ny = sn * ahx + c * ahy;
    }
    const double sdot = ahx * mx + ahy * my;  // s = âᵀ M b̂
    const double c0 = hk * ia, c2 = hk * ib;
    const double f0x = -c0 * (mx - ahx * sdot), f0y = -c0 * (my - ahy * sdot);
    const double f2x = c2 * (nx - bhx * sdot), f2y = c2 * (ny - bhy * sdot);
    out[2 * i0] += f0x;
    out[2 * i0 + 1] += f0y;
    out[2 * i2] += f2x;
    out[2 * i2 + 1] += f2y;
    out[2 * i1] -= f0x + f2x;
    out[2 * i1 + 1] -= f0y + f2y;
  }
}

void Bending::add_force_with(const StateView& s, ForceOut& f, double k, const double* ke) const {
  const bool scaled = !ke_.empty();
  if (flat_ && !scaled)
    add_force_impl<true, false>(s, f, k, ke);
  else if (flat_)
    add_force_impl<true, true>(s, f, k, ke);
  else if (!scaled)
    add_force_impl<false, false>(s, f, k, ke);
  else
    add_force_impl<false, true>(s, f, k, ke);
}

void Bending::add_force(const StateView& s, ForceOut& f) const {
  add_force_with(s, f, k_, ke_.data());
}

void Bending::add_dforce_dparam(const StateView& s, std::string_view param, int,
                                ForceOut& df) const {
  if (param != "k") throw Error("add_dforce_dparam: no derivative in '" + std::string(param) + "'");
  add_force_with(s, df, 1.0, dke_.data());
}

double Bending::energy(const StateView& s) const {
  double sum = 0.0;
  for (std::size_t e = 0; e < idx_.size() / 3; ++e) {
    const Vec2 a = s.x.col(idx_[3 * e + 1]) - s.x.col(idx_[3 * e]);
    const Vec2 b = s.x.col(idx_[3 * e + 2]) - s.x.col(idx_[3 * e + 1]);
    const double la = a.norm(), lb = b.norm();
    if (!(la > kMinLength && lb > kMinLength)) continue;
    const double c = flat_ ? 1.0 : c0_[e], sn = flat_ ? 0.0 : s0_[e];
    sum += k_of(e) * (c * a.dot(b) + sn * (a.x() * b.y() - a.y() * b.x())) / (la * lb);
  }
  return -0.5 * sum;
}

// The constraint C = √2 sin(φ/2), φ = θ - θ0 = atan2(â × m, â·m) with m = M b̂ (the angle
// from â to b̂ less θ0). With a⊥ = (-a_y, a_x), the angle of a has gradient a⊥/|a|², so
//   dφ/da = -a⊥/|a|²,  dφ/db = b⊥/|b|²,  dC/dφ = cos(φ/2)/√2,
// and with a = p1 - p0, b = p2 - p1: dC/dp0 = -dC/da, dC/dp1 = dC/da - dC/db, dC/dp2 = dC/db.
// A degenerate triple (an edge shorter than kMinLength) has C = 0 and dC/dp = 0, as it has no
// force. C is discontinuous at φ = ±π (C² is not): the strand folded back on itself.
void Bending::constraints(const double* x, const uint64_t* which, std::size_t n, double* c,
                          double* dc) const {
  const double r2 = std::sqrt(2.0);
  for (std::size_t q = 0; q < n; ++q, dc += 6) {
    if (which[q] >= idx_.size() / 3)
      throw Error("constraints: element " + std::to_string(which[q]) + " of " +
                  std::to_string(idx_.size() / 3));
    const auto e = static_cast<std::size_t>(which[q]);
    const uint32_t i0 = idx_[3 * e], i1 = idx_[3 * e + 1], i2 = idx_[3 * e + 2];
    const double ax = x[2 * i1] - x[2 * i0], ay = x[2 * i1 + 1] - x[2 * i0 + 1];
    const double bx = x[2 * i2] - x[2 * i1], by = x[2 * i2 + 1] - x[2 * i1 + 1];
    const double a2 = ax * ax + ay * ay, b2 = bx * bx + by * by;
    const double la = std::sqrt(a2), lb = std::sqrt(b2);
    c[q] = 0.0;
    for (int k = 0; k < 6; ++k) dc[k] = 0.0;
    if (!(la > kMinLength && lb > kMinLength)) continue;
    double mx = bx / lb, my = by / lb;  // m = M b̂
    if (!flat_) {
      const double cc = c0_[e], sn = s0_[e], ux = mx, uy = my;
      mx = cc * ux + sn * uy;
      my = -sn * ux + cc * uy;
    }
    const double ahx = ax / la, ahy = ay / la;
    const double phi = std::atan2(ahx * my - ahy * mx, ahx * mx + ahy * my);
    c[q] = r2 * std::sin(0.5 * phi);
    const double g = std::cos(0.5 * phi) / r2;           // dC/dφ
    const double dax = g * ay / a2, day = -g * ax / a2;  // dC/da = -g a⊥/|a|²
    const double dbx = -g * by / b2, dby = g * bx / b2;  // dC/db = g b⊥/|b|²
    dc[0] = -dax;
    dc[1] = -day;
    dc[2] = dax - dbx;
    dc[3] = day - dby;
    dc[4] = dbx;
    dc[5] = dby;
  }
}

// The product in the angle form: with ψ = θ - θ0 and its gradient in the edge vectors
// g = (g_a, g_b) = (-a⊥/|a|², b⊥/|b|²) (a⊥ = R a, R the quarter turn; the angle of a has
// gradient a⊥/|a|²), E = -k/2 cos ψ has the Hessian
//   H = k/2 cos ψ g gᵀ + k/2 sin ψ diag(-S(a), S(b)),  S(u) = R/|u|² - 2 u⊥ uᵀ/|u|⁴
// (S(u) the Hessian of u's angle, symmetric; the cross block of ψ's Hessian is zero). The
// force f = -dE/dp, so gx = (df/dp)ᵀ w = -Dᵀ H D w with D w = (w1 - w0, w2 - w1) and
// Dᵀ (r_a, r_b) = (-r_a, r_a - r_b, r_b). cos ψ = cos θ c0 + sin θ s0, sin ψ = sin θ c0 -
// cos θ s0, cos θ = a·b/(|a||b|), sin θ = a×b/(|a||b|). The same matrix as add_dfdx's (the
// second derivatives of s = âᵀ M b̂ = cos ψ), in fewer operations.
void Bending::add_jacobian_products(const StateView& s, const Field& w, ForceOut& gx,
                                    ForceOut*) const {
  products<false>(s, w, gx, nullptr);
}

void Bending::add_adjoint_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut*,
                                   std::span<double> gp) const {
  if (gp.size() != 1) throw Error("add_adjoint_products: expected 1 slot (k)");
  products<true>(s, w, gx, gp.data());
}

template <bool Params>
void Bending::products(const StateView& s, const Field& w, ForceOut& gx, double* gp) const {
  double dk = 0.0;
  const double* x = s.x.data();
  const double* wd = w.data();
  double* out = gx.data();
  for (std::size_t e = 0; e < idx_.size() / 3; ++e) {
    const uint32_t p0 = idx_[3 * e], p1 = idx_[3 * e + 1], p2 = idx_[3 * e + 2];
    const double ax = x[2 * p1] - x[2 * p0], ay = x[2 * p1 + 1] - x[2 * p0 + 1];
    const double bx = x[2 * p2] - x[2 * p1], by = x[2 * p2 + 1] - x[2 * p1 + 1];
    const double la = std::sqrt(ax * ax + ay * ay), lb = std::sqrt(bx * bx + by * by);
    if (!(la > kMinLength && lb > kMinLength)) continue;
    const double ia = 1.0 / la, ib = 1.0 / lb;
    const double ia2 = ia * ia, ib2 = ib * ib, iab = ia * ib;
    const double ct = (ax * bx + ay * by) * iab, st = (ax * by - ay * bx) * iab;
    double cp = ct, sp = st;  // cos ψ, sin ψ
    if (!flat_) {
      cp = ct * c0_[e] + st * s0_[e];
      sp = st * c0_[e] - ct * s0_[e];
    }
    const double h = 0.5 * k_of(e);
    const double e1 = h * sp, e2 = h * cp;
    const double wax = wd[2 * p1] - wd[2 * p0], way = wd[2 * p1 + 1] - wd[2 * p0 + 1];
    const double wbx = wd[2 * p2] - wd[2 * p1], wby = wd[2 * p2 + 1] - wd[2 * p1 + 1];
    // g_a = -a⊥/|a|² = (ay, -ax)/|a|², g_b = b⊥/|b|² = (-by, bx)/|b|²
    const double gax = ay * ia2, gay = -ax * ia2, gbx = -by * ib2, gby = bx * ib2;
    const double gdw = gax * wax + gay * way + gbx * wbx + gby * wby;  // g · D w
    if constexpr (Params) dk -= 0.5 * (ke_.empty() ? 1.0 : dke_[e]) * sp * gdw;
    const double gw = e2 * gdw;
    // S(u) v = (R v - 2 u⊥ (u·v)/|u|²)/|u|², R v = (-v_y, v_x), u⊥ = (-u_y, u_x)
    const double qa = 2.0 * (ax * wax + ay * way) * ia2, qb = 2.0 * (bx * wbx + by * wby) * ib2;
    const double sax = (-way + ay * qa) * ia2, say = (wax - ax * qa) * ia2;
    const double sbx = (-wby + by * qb) * ib2, sby = (wbx - bx * qb) * ib2;
    const double rax = gw * gax - e1 * sax, ray = gw * gay - e1 * say;  // (H D w)_a
    const double rbx = gw * gbx + e1 * sbx, rby = gw * gby + e1 * sby;  // (H D w)_b
    out[2 * p0] += rax;
    out[2 * p0 + 1] += ray;
    out[2 * p1] += rbx - rax;
    out[2 * p1 + 1] += rby - ray;
    out[2 * p2] -= rbx;
    out[2 * p2 + 1] -= rby;
  }
  if constexpr (Params) gp[0] += dk;
}

// Second derivatives of s = âᵀ M b̂ in the edge vectors (Π_u = I - ûûᵀ, m = M b̂, n = Mᵀ â),
// from ∂â/∂a = Π_a / a (seed, "Gradient of unit distance vector"):
//   ds/da = Π_a m / a,   ds/db = Π_b n / b
//   d2s/da2 = -(Π_a m âᵀ + â mᵀ Π_a + (â·m) Π_a) / a²
//   d2s/db2 = -(Π_b n b̂ᵀ + b̂ nᵀ Π_b + (b̂·n) Π_b) / b²
//   d2s/dadb = Π_a M Π_b / (a b)
// With a = p1 - p0, b = p2 - p1 (da/dp = [-I, I, 0], db/dp = [0, -I, I]) and f = k/2 ds/dp,
// df_i/dp_j = k/2 Σ D_i D_j H over the (a, b) pairs.
void Bending::add_dfdx(const StateView& s, Triplets& J) const {
  const Mat2 id = Mat2::Identity();
  for (std::size_t e = 0; e < idx_.size() / 3; ++e) {
    const uint32_t p[3] = {idx_[3 * e], idx_[3 * e + 1], idx_[3 * e + 2]};
    const Vec2 a = s.x.col(p[1]) - s.x.col(p[0]);
    const Vec2 b = s.x.col(p[2]) - s.x.col(p[1]);
    const double la = a.norm(), lb = b.norm();
    if (!(la > kMinLength && lb > kMinLength)) continue;
    Mat2 M = id;
    if (!flat_) M << c0_[e], s0_[e], -s0_[e], c0_[e];
    const Vec2 ah = a / la, bh = b / lb;
    const Vec2 m = M * bh, n = M.transpose() * ah;
    const Mat2 pa = id - ah * ah.transpose(), pb = id - bh * bh.transpose();
    const Mat2 haa =
        -(pa * m * ah.transpose() + ah * m.transpose() * pa + ah.dot(m) * pa) / (la * la);
    const Mat2 hbb =
        -(pb * n * bh.transpose() + bh * n.transpose() * pb + bh.dot(n) * pb) / (lb * lb);
    const Mat2 hab = pa * M * pb / (la * lb);
    const Mat2 hba = hab.transpose();
    // block (i, j) = da_i da_j haa + da_i db_j hab + db_i da_j hba + db_i db_j hbb with
    // da = (-1, 1, 0), db = (0, -1, 1): the nonzero terms only, in that order
    const double h = 0.5 * k_of(e);
    auto add = [&](int i, int j, const Mat2& blk) {
      J.add_block(p[i], p[j], h * blk(0, 0), h * blk(1, 0), h * blk(0, 1), h * blk(1, 1));
    };
    add(0, 0, haa);
    add(0, 1, -haa + hab);
    add(0, 2, -hab);
    add(1, 0, -haa + hba);
    add(1, 1, haa - hab - hba + hbb);
    add(1, 2, hab - hbb);
    add(2, 0, -hba);
    add(2, 1, hba - hbb);
    add(2, 2, hbb);
  }
}

}  // namespace pinsim::plugins

PINSIM_PLUGIN(pinsim::plugins::Bending)
