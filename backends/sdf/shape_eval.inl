// ShapeTree::eval: the SDF primitives (included by shape.hpp so queries can inline them).
#pragma once

#include <algorithm>
#include <cmath>

namespace pinsim::sdf {
namespace eval_detail {

/// Rotates v by the angle with cos c, sin s.
inline Vec2 rot(double c, double s, const Vec2& v) {
  return {c * v.x() - s * v.y(), s * v.x() + c * v.y()};
}
/// Rotates v by minus that angle.
inline Vec2 rot_inv(double c, double s, const Vec2& v) {
  return {c * v.x() + s * v.y(), -s * v.x() + c * v.y()};
}
inline double sgn(double x) { return x < 0.0 ? -1.0 : 1.0; }

}  // namespace eval_detail

// Exact SDFs after Inigo Quilez, "2D distance functions" (iquilezles.org/articles/distfunctions2d):
// circle |p-c| - r; box |max(q,0)| + min(max(qx,qy),0) with q = |p| - h; rounded box = box with
// h - rc, minus rc; segment/capsule |p - a - h (b-a)| - r, h = clamp((p-a).(b-a)/|b-a|^2, 0, 1);
// uneven capsule; polygon (closest edge, sign by crossing count); arc. Gradients are the
// unit vector from the closest boundary point; at singular points (centres, medial axes,
// points on a zero-thickness segment) a fixed, deterministic choice is made.
template <bool G>
inline Sdf ShapeTree::eval_primitive(const ShapeNode& n, const Vec2& p) const {
  using namespace eval_detail;
  Sdf out;
  switch (n.type) {
    case ShapeType::kCircle: {
      const Vec2 q = p - n.c;
      const double l = q.norm();
      out.d = l - n.r0;
      if constexpr (G) out.g = l > 0.0 ? Vec2(q / l) : Vec2(0.0, 1.0);
      break;
    }
    case ShapeType::kBox:
    case ShapeType::kRoundedBox: {
      const Vec2 q = rot_inv(n.ca, n.sa, p - n.c);
      const double wx = std::abs(q.x()) - n.b.x(), wy = std::abs(q.y()) - n.b.y();
      const double ox = std::max(wx, 0.0), oy = std::max(wy, 0.0);
      // Facing one side (ox or oy zero, the common case) sqrt(o^2) is o exactly and o s / o
      // is s exactly, so the square root and the division are skipped without changing a
      // bit; the bounds keep o^2 a normal number.
      const bool face_y = ox == 0.0 && oy > 1e-150 && oy < 1e150;
      const bool face_x = oy == 0.0 && ox > 1e-150 && ox < 1e150;
      const double outside = face_y ? oy : face_x ? ox : std::sqrt(ox * ox + oy * oy);
      out.d = outside + std::min(std::max(wx, wy), 0.0) - n.r0;
      if constexpr (G) {
        Vec2 g;
        if (face_y)
          g = Vec2(ox * sgn(q.x()), sgn(q.y()));
        else if (face_x)
          g = Vec2(sgn(q.x()), oy * sgn(q.y()));
        else if (outside > 0.0)
          g = Vec2(ox * sgn(q.x()), oy * sgn(q.y())) / outside;
        else if (wx >= wy)
          g = Vec2(sgn(q.x()), 0.0);
        else
          g = Vec2(0.0, sgn(q.y()));
        out.g = rot(n.ca, n.sa, g);
      }
      break;
    }
    case ShapeType::kCapsule: {
      const Vec2 w = p - n.c;
      const double h = std::clamp(w.dot(n.b) * n.k0, 0.0, 1.0);
      const Vec2 q = w - n.b * h;
      const double l = q.norm();
      out.d = l - n.r0;
      if constexpr (G) out.g = l > 0.0 ? Vec2(q / l) : Vec2(-n.sa, n.ca);
      break;
    }
    case ShapeType::kTaperedCapsule: {
      const Vec2 w = p - n.c;
      const Vec2 ex(n.b.y(), -n.b.x());
      const double lx = w.dot(ex), ly = w.dot(n.b);
      const double px = std::abs(lx);
      const double k = -n.k0 * px + n.k1 * ly;
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
        const double h = std::clamp(w.dot(e) / e.squaredNorm(), 0.0, 1.0);
        const Vec2 q = w - e * h;
        const double dd = q.squaredNorm();
        if (dd < best) {
          best = dd;
          bq = q;
          be = i;
        }
        const bool c1 = p.y() >= v[i].y(), c2 = p.y()<v[j].y(), c3 = e.x() * w.y()> e.y() * w.x();
        if ((c1 && c2 && c3) || (!c1 && !c2 && !c3)) inside = !inside;
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
  const Vec2 p = n.transformed ? rot_inv(n.tc, n.ts, pw - n.tt) : pw;
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
    if (n.transformed) out.g = rot(n.tc, n.ts, out.g);
  return out;
}

}  // namespace pinsim::sdf
