// ShapeTree::outline: the tree's boundary as closed rings, primitive by primitive, combined
// through the tree like the distances (see outline.hpp).
#include <algorithm>
#include <cmath>
#include <numbers>
#include <pinsim/scene_field/shape.hpp>

namespace pinsim::sdf {
namespace {

constexpr double kPi = std::numbers::pi;

/// A ring given in a primitive's local frame (x along `ex`, y along `ey`, origin `o`),
/// mapped into the node frame: o + x ex + y ey.
Ring place(const Ring& local, const Vec2& o, const Vec2& ex, const Vec2& ey) {
  Ring out;
  out.reserve(local.size());
  for (const Vec2& p : local) out.push_back(o + p.x() * ex + p.y() * ey);
  return out;
}

}  // namespace

void ShapeTree::add_points_node(uint32_t i, const Transform& parent, std::vector<Vec2>& out) const {
  const ShapeNode& n = nodes_[i];
  const Transform x = n.transformed ? parent.compose(n.tf) : parent;
  if (n.type == ShapeType::kHalfPlane) out.push_back(x.apply(n.c));
  if (n.type >= ShapeType::kUnion)
    for (uint32_t k = 0; k < n.count; ++k) add_points_node(children_[n.first + k], x, out);
}

Rings ShapeTree::outline(double tol, const Ring& clip) const {
  return outline_node(root_, tol, clip, 0.0);
}

// Each primitive's boundary, counter-clockwise: a circle and the corners of a rounded box as
// arcs, a capsule as two half circles, a tapered capsule as the arcs about its ends joined by
// the tangents (normals (+-k1, k0) across and along its axis), an arc as its outer and inner
// arcs joined by half circles about its ends (two circles if it closes), a half-plane as the
// part of `clip` behind it. `frame` is the angle of the node's parent frame in the shape's
// frame, so that arcs get their axis-extreme points as vertices (exact bounds).
Rings ShapeTree::outline_node(uint32_t i, double tol, const Ring& clip_parent, double frame) const {
  const ShapeNode& n = nodes_[i];
  Ring clip = clip_parent;
  if (n.transformed) {
    for (Vec2& p : clip) p = n.tf.apply_inverse(p);
    frame += std::atan2(n.tf.r.s, n.tf.r.c);
  }
  Rings out;
  const Rotation orient{n.ca, n.sa};
  const double turned = frame + std::atan2(n.sa, n.ca);  // the primitive's own frame
  // A ring given in the primitive's own frame, rotated and moved to its place.
  auto placed = [&n, &orient](const Ring& local) {
    Ring ring;
    for (const Vec2& p : local) ring.push_back(n.c + orient.apply(p));
    return ring;
  };
  switch (n.type) {
    case ShapeType::kCircle:
      out.rings.push_back(circle_ring(n.c, n.r0, tol, frame));
      break;
    case ShapeType::kBox:
    case ShapeType::kRoundedBox: {
      Ring local;
      const double hx = n.b.x(), hy = n.b.y();
      const Vec2 corners[4] = {{hx, hy}, {-hx, hy}, {-hx, -hy}, {hx, -hy}};
      for (int k = 0; k < 4; ++k) {
        if (n.r0 > 0.0)
          add_arc(local, corners[k], n.r0, 0.5 * kPi * k, 0.5 * kPi * (k + 1), tol, turned);
        else
          local.push_back(corners[k]);
      }
      out.rings.push_back(placed(local));
      break;
    }
    case ShapeType::kCapsule: {
      Ring local;
      const double h = n.b.x();
      if (n.r0 > 0.0) {
        add_arc(local, Vec2(h, 0.0), n.r0, -0.5 * kPi, 0.5 * kPi, tol, turned);
        add_arc(local, Vec2(-h, 0.0), n.r0, 0.5 * kPi, 1.5 * kPi, tol, turned);
      } else {
        local = {Vec2(-h, 0.0), Vec2(h, 0.0)};
      }
      out.rings.push_back(placed(local));
      break;
    }
    case ShapeType::kTaperedCapsule: {
      Ring local;
      const double phi = std::atan2(n.k0, n.k1);
      const double axes = frame + std::atan2(-n.b.x(), n.b.y());  // of (ex, ey)
      add_arc(local, Vec2(0.0, n.h), n.r1, phi, kPi - phi, tol, axes);
      add_arc(local, Vec2(0.0, 0.0), n.r0, kPi - phi, 2.0 * kPi + phi, tol, axes);
      if (local.size() > 1 && local.back() == local.front()) local.pop_back();
      out.rings.push_back(place(local, n.c, Vec2(n.b.y(), -n.b.x()), n.b));
      break;
    }
    case ShapeType::kPolygon:
      out.rings.emplace_back(verts_.begin() + n.first, verts_.begin() + n.first + n.count);
      break;
    case ShapeType::kArc: {
      const Vec2 ey(n.ca, n.sa), ex(n.sa, -n.ca);
      const double half = std::atan2(n.k0, n.k1);
      const double axes = frame + std::atan2(-n.ca, n.sa);  // of (ex, ey)
      const double outer = n.r0 + n.r1, inner = n.r0 - n.r1;
      if (half >= kPi) {  // a closed ring: the outer circle and the inner one, clockwise
        out.rings.push_back(place(circle_ring(Vec2::Zero(), outer, tol, axes), n.c, ex, ey));
        if (inner > 0.0) {
          Ring in = circle_ring(Vec2::Zero(), inner, tol, axes);
          std::reverse(in.begin(), in.end());
          out.rings.push_back(place(in, n.c, ex, ey));
        }
        break;
      }
      const double a0 = 0.5 * kPi - half, a1 = 0.5 * kPi + half;
      Ring local;
      add_arc(local, Vec2::Zero(), outer, a0, a1, tol, axes);
      add_arc(local, n.r0 * Vec2(std::cos(a1), std::sin(a1)), n.r1, a1, a1 + kPi, tol, axes);
      Ring back;
      add_arc(back, Vec2::Zero(), std::max(inner, 0.0), a0, a1, tol, axes);
      local.insert(local.end(), back.rbegin(), back.rend());
      add_arc(local, n.r0 * Vec2(std::cos(a0), std::sin(a0)), n.r1, a0 + kPi, a0 + 2.0 * kPi, tol,
              axes);
      out.rings.push_back(place(local, n.c, ex, ey));
      break;
    }
    case ShapeType::kHalfPlane: {
      Ring r = clip_half_plane(clip, n.c, n.b);
      if (r.size() >= 3) out.rings.push_back(std::move(r));
      break;
    }
    case ShapeType::kUnion:
    case ShapeType::kIntersection:
    case ShapeType::kSubtraction: {
      std::vector<Rings> parts;
      for (uint32_t k = 0; k < n.count; ++k)
        parts.push_back(outline_node(children_[n.first + k], tol, clip, frame));
      const RingOp op = n.type == ShapeType::kUnion          ? RingOp::kUnion
                        : n.type == ShapeType::kIntersection ? RingOp::kIntersection
                                                             : RingOp::kSubtraction;
      out = parts.size() == 1 ? parts[0] : combine(parts, op);
      break;
    }
    case ShapeType::kInside:
      out = outline_node(children_[n.first], tol, clip, frame);
      for (Ring& r : out.rings) std::reverse(r.begin(), r.end());
      out.complement = !out.complement;
      break;
  }
  if (n.transformed)
    for (Ring& r : out.rings)
      for (Vec2& p : r) p = n.tf.apply(p);
  return out;
}

}  // namespace pinsim::sdf
