#include <algorithm>
#include <cmath>
#include <numbers>
#include <pinsim/scene_field/outline.hpp>

namespace pinsim::sdf {
namespace {

/// An edge piece kept for the result.
struct Seg {
  Vec2 a, b;
};

/// Segments per arc of `sweep` rad and radius r whose chords stay within tol of it: a chord
/// of angle h lies r (1 - cos(h / 2)) from the arc.
int arc_segments(double r, double sweep, double tol) {
  if (!(r > 0.0) || !(sweep > 0.0)) return 1;
  const double x = 1.0 - std::min(tol / r, 2.0);
  const double h = 2.0 * std::acos(std::max(x, -1.0));
  const double n = h > 0.0 ? std::ceil(sweep / h) : 1 << 16;
  return static_cast<int>(std::clamp(n, 1.0, static_cast<double>(1 << 16)));
}

/// Parameters t in (0, 1) where edge a->b crosses an edge of `other`'s rings.
void crossings(const Vec2& a, const Vec2& b, const Rings& other, std::vector<double>& ts) {
  for (const Ring& r : other.rings)
    for (std::size_t q = 0; q < r.size(); ++q) {
      const Vec2& c = r[q];
      const Vec2& d = r[(q + 1) % r.size()];
      const double den = cross(b - a, d - c);
      if (den == 0.0) continue;
      const double t = cross(c - a, d - c) / den, u = cross(c - a, b - a) / den;
      if (t > 1e-12 && t < 1.0 - 1e-12 && u >= 0.0 && u <= 1.0) ts.push_back(t);
    }
}

/// Whether a piece of part k with midpoint m belongs to the boundary of the result.
bool keep(const std::vector<Rings>& parts, std::size_t k, const Vec2& m, RingOp op) {
  for (std::size_t j = 0; j < parts.size(); ++j) {
    if (j == k) continue;
    const bool in = parts[j].contains(m);
    switch (op) {
      case RingOp::kUnion:
        if (in) return false;
        break;
      case RingOp::kIntersection:
        if (!in) return false;
        break;
      case RingOp::kSubtraction:
        // the first part's boundary outside every other part; another part's boundary
        // inside the first and outside the rest
        if (j == 0 ? !in : in) return false;
        break;
    }
  }
  return true;
}

/// Chains pieces into closed rings by matching each end to the next start (within tol).
std::vector<Ring> chain(const std::vector<Seg>& segs, double tol) {
  std::vector<Ring> out;
  std::vector<bool> used(segs.size(), false);
  for (std::size_t s0 = 0; s0 < segs.size(); ++s0) {
    if (used[s0]) continue;
    used[s0] = true;
    Ring ring{segs[s0].a};
    Vec2 end = segs[s0].b;
    std::size_t cur = s0;
    while ((end - ring.front()).norm() > tol) {
      std::size_t next = segs.size();
      // pieces of one edge chain follow each other: search from the current one on
      for (std::size_t q = 1; q < segs.size() && next == segs.size(); ++q) {
        const std::size_t s = (cur + q) % segs.size();
        if (!used[s] && (segs[s].a - end).norm() <= tol) next = s;
      }
      if (next == segs.size()) break;  // an open end (a touching configuration): close it
      used[next] = true;
      ring.push_back(segs[next].a);
      end = segs[next].b;
      cur = next;
    }
    if (ring.size() >= 2) out.push_back(std::move(ring));
  }
  return out;
}

}  // namespace

bool Rings::contains(const Vec2& p) const {
  bool in = false;
  for (const Ring& v : rings)
    for (std::size_t i = 0, j = v.size() - 1; i < v.size(); j = i++)
      if ((v[i].y() > p.y()) != (v[j].y() > p.y())) {
        const double x =
            v[j].x() + (p.y() - v[j].y()) / (v[i].y() - v[j].y()) * (v[i].x() - v[j].x());
        if (p.x() < x) in = !in;
      }
  return in != complement;
}

Rings combine(const std::vector<Rings>& parts, RingOp op) {
  Rings out;
  if (parts.empty()) return out;
  std::vector<Seg> kept;
  double size = 0.0;
  std::vector<double> ts;
  for (std::size_t k = 0; k < parts.size(); ++k)
    for (const Ring& r : parts[k].rings)
      for (std::size_t i = 0; i < r.size(); ++i) {
        const Vec2 a = r[i], b = r[(i + 1) % r.size()];
        if (a == b) continue;
        size = std::max({size, a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff()});
        ts.assign({0.0, 1.0});
        for (std::size_t j = 0; j < parts.size(); ++j)
          if (j != k) crossings(a, b, parts[j], ts);
        std::sort(ts.begin(), ts.end());
        for (std::size_t q = 0; q + 1 < ts.size(); ++q) {
          if (ts[q + 1] - ts[q] < 1e-12) continue;
          const Vec2 p0 = ts[q] == 0.0 ? a : Vec2(a + ts[q] * (b - a));
          const Vec2 p1 = ts[q + 1] == 1.0 ? b : Vec2(a + ts[q + 1] * (b - a));
          if (!keep(parts, k, 0.5 * (p0 + p1), op)) continue;
          // a subtracted part's boundary faces the other way in the result
          if (op == RingOp::kSubtraction && k > 0)
            kept.push_back({p1, p0});
          else
            kept.push_back({p0, p1});
        }
      }
  out.rings = chain(kept, 1e-9 * std::max(size, 1.0));
  bool any = false, all = true;
  for (const Rings& p : parts) {
    any = any || p.complement;
    all = all && p.complement;
  }
  switch (op) {
    case RingOp::kUnion:
      out.complement = any;
      break;
    case RingOp::kIntersection:
      out.complement = all;
      break;
    case RingOp::kSubtraction: {
      bool rest = false;
      for (std::size_t k = 1; k < parts.size(); ++k) rest = rest || parts[k].complement;
      out.complement = parts[0].complement && !rest;
      break;
    }
  }
  return out;
}

void add_arc(Ring& out, const Vec2& c, double r, double a0, double a1, double tol, double frame) {
  const int n = arc_segments(r, a1 - a0, tol);
  std::vector<double> angles;
  for (int k = 0; k <= n; ++k) angles.push_back(k == n ? a1 : a0 + (a1 - a0) * k / n);
  constexpr double kQuarter = 0.5 * std::numbers::pi;
  for (double a = kQuarter * std::ceil((a0 + frame) / kQuarter) - frame; a < a1; a += kQuarter)
    if (a > a0) angles.push_back(a);
  std::sort(angles.begin(), angles.end());
  for (const double a : angles) {
    const Vec2 p = c + r * Vec2(std::cos(a), std::sin(a));
    if (out.empty() || out.back() != p) out.push_back(p);
  }
}

Ring circle_ring(const Vec2& c, double r, double tol, double frame) {
  const int n = 4 * std::max(2, (arc_segments(r, 2.0 * std::numbers::pi, tol) + 3) / 4);
  Ring out;
  out.reserve(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const double a = 2.0 * std::numbers::pi * k / n - frame;
    out.push_back(c + r * Vec2(std::cos(a), std::sin(a)));
  }
  return out;
}

Ring clip_half_plane(const Ring& poly, const Vec2& point, const Vec2& normal) {
  Ring out;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Vec2& a = poly[i];
    const Vec2& b = poly[(i + 1) % poly.size()];
    const double da = (a - point).dot(normal), db = (b - point).dot(normal);
    if (da <= 0.0) out.push_back(a);
    if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0))
      out.push_back(a + (da / (da - db)) * (b - a));
  }
  return out;
}

}  // namespace pinsim::sdf
