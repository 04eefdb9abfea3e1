// ShapeTree::eval: the SDF primitives (included by shape.hpp so queries can inline them).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace pinsim::sdf {
namespace eval_detail {

inline double sgn(double x) { return x < 0.0 ? -1.0 : 1.0; }

// std::max, std::min and std::clamp on doubles, the same results (NaNs too) without the
// data-dependent branches GCC otherwise emits for them, which random queries mispredict:
// maxsd(x, y) is x > y ? x : y, so std::max(a, b) = (a < b) ? b : a is maxsd(b, a).
inline double max_of(double a, double b) {
#if defined(__SSE2__)
  return _mm_cvtsd_f64(_mm_max_sd(_mm_set_sd(b), _mm_set_sd(a)));
#else
  return std::max(a, b);
#endif
}
/// std::min(a, b) = (b < a) ? b : a = minsd(b, a).
inline double min_of(double a, double b) {
#if defined(__SSE2__)
  return _mm_cvtsd_f64(_mm_min_sd(_mm_set_sd(b), _mm_set_sd(a)));
#else
  return std::min(a, b);
#endif
}
/// c ? a : b, by bit masks rather than a branch.
inline double select_of(bool c, double a, double b) {
  uint64_t ia = 0, ib = 0;
  std::memcpy(&ia, &a, sizeof a);
  std::memcpy(&ib, &b, sizeof b);
  const uint64_t m = uint64_t{0} - static_cast<uint64_t>(c);
  const uint64_t r = (ia & m) | (ib & ~m);
  double out = 0.0;
  std::memcpy(&out, &r, sizeof out);
  return out;
}
/// std::clamp(v, lo, hi) for lo <= hi.
inline double clamp_of(double v, double lo, double hi) { return min_of(max_of(v, lo), hi); }

}  // namespace eval_detail

// Exact SDFs after Inigo Quilez, "2D distance functions" (iquilezles.org/articles/distfunctions2d):
// box |max(q,0)| + min(max(qx,qy),0) with q = |p| - h in the box frame; rounded box = box with
// h - rc, minus rc; circle = rounded box with h = 0; segment/capsule = rounded box with
// h = (|b - a| / 2, 0) in the frame of the segment's midpoint and axis; uneven capsule; polygon
// (closest edge, sign by crossing count); arc. Gradients are the unit vector from the closest
// boundary point; at singular points (centres, medial axes, points on a zero-thickness segment) a
// fixed, deterministic choice is made.

// Box, rounded box, circle and capsule: one formula for all four, so that a random query
// does not mispredict which it is; inlined where the grid evaluates its candidates.
template <bool G>
[[gnu::always_inline]] inline Sdf ShapeTree::eval_box(const ShapeNode& n, const Vec2& p) {
  using namespace eval_detail;
  Sdf out;
  const Vec2 q = Rotation{n.ca, n.sa}.apply_inverse(p - n.c);
  const double wx = std::abs(q.x()) - n.b.x(), wy = std::abs(q.y()) - n.b.y();
  const double ox = max_of(wx, 0.0), oy = max_of(wy, 0.0);
  const double outside = std::sqrt(ox * ox + oy * oy);
  out.d = outside + min_of(max_of(wx, wy), 0.0) - n.r0;
  if constexpr (G) {
    Vec2 g;
    if (outside > 0.0)
      g = Vec2(ox * sgn(q.x()), oy * sgn(q.y())) / outside;
    else if (wx > wy)
      g = Vec2(sgn(q.x()), 0.0);
    else  // also a circle's centre and a capsule's axis: the local +-y
      g = Vec2(0.0, sgn(q.y()));
    out.g = Rotation{n.ca, n.sa}.apply(g);
  }
  return out;
}

template <bool G>
inline Sdf ShapeTree::eval_primitive(const ShapeNode& n, const Vec2& p) const {
  using namespace eval_detail;
  Sdf out;
  switch (n.type) {
    case ShapeType::kCircle:   // a rounded box of half size 0: the same bits as |p - c| - r
    case ShapeType::kCapsule:  // a rounded box of half size (|b - a| / 2, 0)
    case ShapeType::kBox:
    case ShapeType::kRoundedBox:
      return eval_box<G>(n, p);
    case ShapeType::kTaperedCapsule: {
      const Vec2 w = p - n.c;
      const Vec2 ex(n.b.y(), -n.b.x());
      const double lx = w.dot(ex), ly = w.dot(n.b);
      const double px = std::abs(lx);
      const double k = -n.k0 * px + n.k1 * ly;
      if constexpr (!G) {  // the three regions' distances, selected without a branch
        const double lh = ly - n.h;
        const double d0 = std::sqrt(px * px + ly * ly) - n.r0;
        const double d1 = std::sqrt(px * px + lh * lh) - n.r1;
        const double d2 = n.k1 * px + n.k0 * ly - n.r0;
        out.d = select_of(k < 0.0, d0, select_of(k > n.k1 * n.h, d1, d2));
        break;
      }
      Vec2 g;
      if (k < 0.0) {
        const double l = std::sqrt(px * px + ly * ly);
        out.d = l - n.r0;
        g = l > 0.0 ? Vec2(px / l, ly / l) : Vec2(0.0, -1.0);
      } else if (k > n.k1 * n.h) {
        const double l = std::sqrt(px * px + (ly - n.h) * (ly - n.h));
        out.d = l - n.r1;
        g = l > 0.0 ? Vec2(px / l, (ly - n.h) / l) : Vec2(0.0, 1.0);
      } else {
        out.d = n.k1 * px + n.k0 * ly - n.r0;
        g = Vec2(n.k1, n.k0);
      }
      if constexpr (G) out.g = (sgn(lx) * g.x()) * ex + g.y() * n.b;
      break;
    }
    case ShapeType::kPolygon: {
      const Vec2* v = verts_.data() + n.first;
      const uint32_t m = n.count;
      double best = HUGE_VAL;
      Vec2 bq(0.0, 0.0);
      uint32_t be = 0;
      bool inside = false;
      for (uint32_t i = 0, j = m - 1; i < m; j = i, ++i) {
        // edge from v[i] to v[j] (iq's loop); crossing test on the same edge
        const Vec2 e = v[j] - v[i];
        const Vec2 w = p - v[i];
        const double h = clamp_of(w.dot(e) / e.squaredNorm(), 0.0, 1.0);
        const Vec2 q = w - e * h;
        const double dd = q.squaredNorm();
        if constexpr (G) {
          if (dd < best) {
            best = dd;
            bq = q;
            be = i;
          }
        } else {
          best = min_of(best, dd);  // the same as the branch above, without one
        }
        // the crossing: all three conditions true or all false, in bit operations
        const bool c1 = p.y() >= v[i].y(), c2 = p.y()<v[j].y(), c3 = e.x() * w.y()> e.y() * w.x();
        inside ^= !((c1 ^ c2) | (c2 ^ c3));
      }
      const double s = inside ? -1.0 : 1.0;
      const double l = std::sqrt(best);
      out.d = s * l;
      if constexpr (G) {
        if (l > 0.0) {
          out.g = s * bq / l;
        } else {  // on the boundary: outward normal of the edge (counter-clockwise polygon)
          const Vec2 e = v[be] - v[be == 0 ? m - 1 : be - 1];
          out.g = Vec2(e.y(), -e.x()) / e.norm();
        }
      }
      break;
    }
    case ShapeType::kArc: {
      const Vec2 w = p - n.c;
      const Vec2 ey(n.ca, n.sa), ex(n.sa, -n.ca);
      const double lx = w.dot(ex), ly = w.dot(ey);
      const double px = std::abs(lx);
      Vec2 g;
      if (n.k1 * px > n.k0 * ly) {  // beyond the aperture: nearest is an end point
        const Vec2 q(px - n.k0 * n.r0, ly - n.k1 * n.r0);
        const double l = q.norm();
        out.d = l - n.r1;
        g = l > 0.0 ? Vec2(q / l) : Vec2(n.k0, n.k1);
      } else {
        const double l = std::sqrt(px * px + ly * ly);
        out.d = std::abs(l - n.r0) - n.r1;
        g = l > 0.0 ? Vec2(Vec2(px, ly) * (sgn(l - n.r0) / l)) : Vec2(0.0, -1.0);
      }
      if constexpr (G) out.g = (sgn(lx) * g.x()) * ex + g.y() * ey;
      break;
    }
    case ShapeType::kHalfPlane: {
      out.d = (p - n.c).dot(n.b);
      if constexpr (G) out.g = n.b;
      break;
    }
    default:
      break;
  }
  return out;
}

template <bool G>
inline Sdf ShapeTree::eval_node(uint32_t i, const Vec2& pw) const {
  using namespace eval_detail;
  const ShapeNode& n = nodes_[i];
  const Vec2 p = n.transformed ? n.tf.apply_inverse(pw) : pw;
  Sdf out;
  switch (n.type) {
    case ShapeType::kUnion: {
      for (uint32_t k = 0; k < n.count; ++k) {
        const Sdf s = eval_node<G>(children_[n.first + k], p);
        if (k == 0 || s.d < out.d) out = s;
      }
      break;
    }
    case ShapeType::kIntersection: {
      for (uint32_t k = 0; k < n.count; ++k) {
        const Sdf s = eval_node<G>(children_[n.first + k], p);
        if (k == 0 || s.d > out.d) out = s;
      }
      break;
    }
    case ShapeType::kSubtraction: {
      out = eval_node<G>(children_[n.first], p);
      for (uint32_t k = 1; k < n.count; ++k) {
        Sdf s = eval_node<G>(children_[n.first + k], p);
        if (-s.d > out.d) {
          out.d = -s.d;
          if constexpr (G) out.g = -s.g;
        }
      }
      break;
    }
    case ShapeType::kInside: {
      out = eval_node<G>(children_[n.first], p);
      out.d = -out.d;
      if constexpr (G) out.g = -out.g;
      break;
    }
    default:
      out = eval_primitive<G>(n, p);
  }
  if constexpr (G)
    if (n.transformed) out.g = n.tf.r.apply(out.g);
  return out;
}

}  // namespace pinsim::sdf
