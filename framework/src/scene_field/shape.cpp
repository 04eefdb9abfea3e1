#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numbers>
#include <pinsim/scene_field/shape.hpp>
#include <string_view>

namespace pinsim::sdf {
namespace {

constexpr int kMaxDepth = 32;

/// True if closed segments pq and rs share a point.
bool segments_touch(const Vec2& p, const Vec2& q, const Vec2& r, const Vec2& s) {
  auto orient = [](const Vec2& a, const Vec2& b, const Vec2& c) {
    const double v = cross(b - a, c - a);
    return v > 0.0 ? 1 : (v < 0.0 ? -1 : 0);
  };
  auto on_seg = [](const Vec2& a, const Vec2& b, const Vec2& c) {
    return std::min(a.x(), b.x()) <= c.x() && c.x() <= std::max(a.x(), b.x()) &&
           std::min(a.y(), b.y()) <= c.y() && c.y() <= std::max(a.y(), b.y());
  };
  const int o1 = orient(p, q, r), o2 = orient(p, q, s), o3 = orient(r, s, p), o4 = orient(r, s, q);
  if (o1 != o2 && o3 != o4) return true;
  return (o1 == 0 && on_seg(p, q, r)) || (o2 == 0 && on_seg(p, q, s)) ||
         (o3 == 0 && on_seg(r, s, p)) || (o4 == 0 && on_seg(r, s, q));
}

Aabb transform_box(const Aabb& b, const Transform& tf) {
  if (!b.bounded || b.empty()) return b;
  Aabb out;
  for (int k = 0; k < 4; ++k) {
    const Vec2 corner((k & 1) ? b.hi.x() : b.lo.x(), (k & 2) ? b.hi.y() : b.lo.y());
    out.add(tf.apply(corner));
  }
  return out;
}

bool positive(double x) { return x > 0.0; }
bool non_negative(double x) { return x >= 0.0; }

/// What a per-type parser may add to the tree besides its own node.
struct TreeParts {
  std::vector<Vec2>& verts;                            ///< polygon vertices
  std::vector<uint32_t>& children;                     ///< child node indices
  std::vector<std::pair<Vec2, Vec2>>& ends;            ///< capsule ends as given
  std::function<uint32_t(const JsonIn&)> parse_child;  ///< parses a node one level deeper
};

/// Reads one shape type's keys into its node (the transform is already read).
using ShapeParser = void (*)(const JsonIn& j, ShapeNode& n, TreeParts& tree);

// "transform": {"translate": [x, y], "rotate": angle}, both optional.
void read_transform(const JsonIn& tr, ShapeNode& n) {
  tr.only({"translate", "rotate"});
  n.transformed = true;
  n.tf.t = tr.vec2("translate", Vec2(0.0, 0.0));
  n.tf.r = Rotation::from_angle(tr.number("rotate", 0.0));
}

// circle: center, radius > 0; evaluated as a rounded box of half size 0.
void parse_circle(const JsonIn& j, ShapeNode& n, TreeParts&) {
  j.only({"type", "transform", "center", "radius"});
  n.type = ShapeType::kCircle;
  n.c = j.vec2("center");
  n.r0 = j.number_if("radius", positive, "must be > 0");
}

// box and rounded_box: center, half_size > 0, angle; a rounded box's corner_radius is at
// most the smaller half size and is taken off the half size.
void parse_box_like(const JsonIn& j, ShapeNode& n, bool rounded) {
  if (rounded)
    j.only({"type", "transform", "center", "half_size", "angle", "corner_radius"});
  else
    j.only({"type", "transform", "center", "half_size", "angle"});
  n.type = rounded ? ShapeType::kRoundedBox : ShapeType::kBox;
  n.c = j.vec2("center");
  const Vec2 h = j.vec2("half_size");
  if (!(h.x() > 0.0 && h.y() > 0.0))
    j.fail("half_size", "both components must be > 0, got " + JsonIn::show(j.json()["half_size"]));
  const double a = j.number("angle", 0.0);
  n.ca = std::cos(a);
  n.sa = std::sin(a);
  if (rounded) {
    const double cr = j.number("corner_radius");
    if (!(cr >= 0.0 && cr <= std::min(h.x(), h.y())))
      j.fail("corner_radius", "must be in [0, min(half_size)] = [0, " +
                                  std::to_string(std::min(h.x(), h.y())) + "], got " +
                                  JsonIn::show(j.json()["corner_radius"]));
    n.r0 = cr;
    n.b = h - Vec2(cr, cr);
  } else {
    n.b = h;
  }
}
void parse_box(const JsonIn& j, ShapeNode& n, TreeParts&) { parse_box_like(j, n, false); }
void parse_rounded_box(const JsonIn& j, ShapeNode& n, TreeParts&) { parse_box_like(j, n, true); }

// capsule: ends a, b and radius >= 0; evaluated as a rounded box of half size
// (|b - a| / 2, 0) about the midpoint, rotated to the axis: the distance to the segment,
// minus the radius.
void parse_capsule(const JsonIn& j, ShapeNode& n, TreeParts& tree) {
  j.only({"type", "transform", "a", "b", "radius"});
  n.type = ShapeType::kCapsule;
  const Vec2 a = j.vec2("a"), ab = j.vec2("b") - a;
  n.first = static_cast<uint32_t>(tree.ends.size());
  tree.ends.emplace_back(a, j.vec2("b"));
  n.r0 = j.number_if("radius", non_negative, "must be >= 0");
  const double len = ab.norm();
  n.c = a + 0.5 * ab;
  n.b = Vec2(0.5 * len, 0.0);
  if (len > 0.0) {
    n.ca = ab.x() / len;
    n.sa = ab.y() / len;
  }
}

// tapered_capsule: ends a, b with radii radius_a, radius_b, neither end disc containing
// the other; stored in iq's form (axis, a and b constants).
void parse_tapered_capsule(const JsonIn& j, ShapeNode& n, TreeParts& tree) {
  j.only({"type", "transform", "a", "b", "radius_a", "radius_b"});
  n.type = ShapeType::kTaperedCapsule;
  n.c = j.vec2("a");
  const Vec2 ab = j.vec2("b") - n.c;
  n.first = static_cast<uint32_t>(tree.ends.size());
  tree.ends.emplace_back(n.c, j.vec2("b"));
  n.r0 = j.number_if("radius_a", non_negative, "must be >= 0");
  n.r1 = j.number_if("radius_b", non_negative, "must be >= 0");
  n.h = ab.norm();
  if (!(std::abs(n.r0 - n.r1) < n.h))
    j.fail("b", "need |radius_a - radius_b| < |b - a| (one disc may not contain the other)");
  n.b = ab / n.h;                       // axis (local +y)
  n.k0 = (n.r0 - n.r1) / n.h;           // iq's b
  n.k1 = std::sqrt(1.0 - n.k0 * n.k0);  // iq's a
}

// polygon: at least 3 points, a simple polygon of non-zero area; its vertices are added
// counter-clockwise to the tree's vertex list.
void parse_polygon(const JsonIn& j, ShapeNode& n, TreeParts& tree) {
  j.only({"type", "transform", "points"});
  n.type = ShapeType::kPolygon;
  const auto& pts = j.array("points");
  if (pts.size() < 3) j.fail("points", "need at least 3 points, got " + std::to_string(pts.size()));
  std::vector<Vec2> v;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (!JsonIn::is_vec2(pts[i]))
      j.fail("points[" + std::to_string(i) + "]", "expected [x, y], got " + JsonIn::show(pts[i]));
    v.emplace_back(pts[i][0].get<double>(), pts[i][1].get<double>());
  }
  double area2 = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) area2 += cross(v[i], v[(i + 1) % v.size()]);
  if (!(std::abs(area2) > 0.0)) j.fail("points", "polygon has zero area");
  const std::size_t m = v.size();
  for (std::size_t i = 0; i < m; ++i) {
    if (v[i] == v[(i + 1) % m])
      j.fail("points[" + std::to_string(i) + "]", "repeats the next point");
    for (std::size_t k = i + 2; k < m; ++k) {
      if (i == 0 && k == m - 1) continue;  // adjacent through the wrap
      if (segments_touch(v[i], v[(i + 1) % m], v[k], v[(k + 1) % m]))
        j.fail("points", "polygon is not simple: edge " + std::to_string(i) + " touches edge " +
                             std::to_string(k));
    }
  }
  if (area2 < 0.0) std::reverse(v.begin(), v.end());  // counter-clockwise from here on
  n.first = static_cast<uint32_t>(tree.verts.size());
  n.count = static_cast<uint32_t>(m);
  tree.verts.insert(tree.verts.end(), v.begin(), v.end());
}

// arc: a ring sector of radius > 0 and thickness > 0 from start_angle to end_angle
// (sweep in (0, 2 pi]); local +y is the middle direction.
void parse_arc(const JsonIn& j, ShapeNode& n, TreeParts&) {
  j.only({"type", "transform", "center", "radius", "start_angle", "end_angle", "thickness"});
  n.type = ShapeType::kArc;
  n.c = j.vec2("center");
  n.r0 = j.number_if("radius", positive, "must be > 0");
  n.r1 = 0.5 * j.number_if("thickness", positive, "must be > 0");
  const double a0 = j.number("start_angle");
  const double a1 = j.number("end_angle");
  const double sweep = a1 - a0;
  if (!(sweep > 0.0 && sweep <= 2.0 * std::numbers::pi + 1e-12))
    j.fail("end_angle",
           "end_angle - start_angle must be in (0, 2 pi], got " + std::to_string(sweep));
  const double mid = a0 + 0.5 * sweep;
  n.ca = std::cos(mid);
  n.sa = std::sin(mid);
  n.k0 = std::sin(0.5 * std::min(sweep, 2.0 * std::numbers::pi));
  n.k1 = std::cos(0.5 * std::min(sweep, 2.0 * std::numbers::pi));
}

// half_plane: a point on the boundary and the outward normal (non-zero, normalized).
void parse_half_plane(const JsonIn& j, ShapeNode& n, TreeParts&) {
  j.only({"type", "transform", "point", "normal"});
  n.type = ShapeType::kHalfPlane;
  n.c = j.vec2("point");
  const Vec2 nn = j.vec2("normal");
  if (!(nn.norm() > 0.0)) j.fail("normal", "must be non-zero");
  n.b = nn / nn.norm();
}

// union, intersection and subtraction: "shapes", at least one (two for a subtraction),
// parsed one level deeper and added to the tree's child list.
void parse_boolean(const JsonIn& j, ShapeNode& n, TreeParts& tree, ShapeType type) {
  j.only({"type", "transform", "shapes"});
  n.type = type;
  const auto& arr = j.array("shapes");
  const std::size_t need = n.type == ShapeType::kSubtraction ? 2 : 1;
  if (arr.size() < need)
    j.fail("shapes",
           "need at least " + std::to_string(need) + " shapes, got " + std::to_string(arr.size()));
  std::vector<uint32_t> kids;
  for (std::size_t i = 0; i < arr.size(); ++i)
    kids.push_back(
        tree.parse_child(JsonIn(arr[i], j.at("shapes[" + std::to_string(i) + "]"), j.ctx())));
  n.first = static_cast<uint32_t>(tree.children.size());
  n.count = static_cast<uint32_t>(kids.size());
  tree.children.insert(tree.children.end(), kids.begin(), kids.end());
}
void parse_union(const JsonIn& j, ShapeNode& n, TreeParts& tree) {
  parse_boolean(j, n, tree, ShapeType::kUnion);
}
void parse_intersection(const JsonIn& j, ShapeNode& n, TreeParts& tree) {
  parse_boolean(j, n, tree, ShapeType::kIntersection);
}
void parse_subtraction(const JsonIn& j, ShapeNode& n, TreeParts& tree) {
  parse_boolean(j, n, tree, ShapeType::kSubtraction);
}

// inside: the complement of "shape" (a container), parsed one level deeper.
void parse_inside(const JsonIn& j, ShapeNode& n, TreeParts& tree) {
  j.only({"type", "transform", "shape"});
  n.type = ShapeType::kInside;
  const uint32_t kid = tree.parse_child(j.object("shape"));
  n.first = static_cast<uint32_t>(tree.children.size());
  n.count = 1;
  tree.children.push_back(kid);
}

/// The parser of each shape type, keyed by its "type" name (in the order the unknown-type
/// error lists them).
struct ShapeParserEntry {
  std::string_view type;
  ShapeParser parse;
};
constexpr std::array<ShapeParserEntry, 12> kShapeParsers = {{
    {"circle", parse_circle},
    {"box", parse_box},
    {"rounded_box", parse_rounded_box},
    {"capsule", parse_capsule},
    {"tapered_capsule", parse_tapered_capsule},
    {"polygon", parse_polygon},
    {"arc", parse_arc},
    {"half_plane", parse_half_plane},
    {"union", parse_union},
    {"intersection", parse_intersection},
    {"subtraction", parse_subtraction},
    {"inside", parse_inside},
}};

// The parser for `type`, or none.
ShapeParser find_shape_parser(std::string_view type) {
  for (const ShapeParserEntry& e : kShapeParsers)
    if (e.type == type) return e.parse;
  return nullptr;
}

// "a, b, c": the known shape types, for the unknown-type error.
std::string shape_type_names() {
  std::string names;
  for (const ShapeParserEntry& e : kShapeParsers)
    names += (names.empty() ? "" : ", ") + std::string(e.type);
  return names;
}

}  // namespace

ShapeTree ShapeTree::parse(const JsonIn& j) {
  ShapeTree t;
  t.root_ = t.parse_node(j, 0);
  const ShapeNode& r = t.nodes_[t.root_];
  t.root_primitive_ = r.type < ShapeType::kUnion && !r.transformed;
  return t;
}

uint32_t ShapeTree::parse_node(const JsonIn& j, int depth) {
  if (!j.json().is_object()) j.fail("", "expected a shape object, got " + JsonIn::show(j.json()));
  if (depth > kMaxDepth) j.fail("", "shapes nested deeper than 32 levels");
  const std::string type = j.string("type");
  ShapeNode n;
  if (j.has("transform")) read_transform(j.object("transform"), n);
  const ShapeParser parse = find_shape_parser(type);
  if (!parse)
    j.fail("type", "unknown shape type '" + type + "' (expected " + shape_type_names() + ")");
  TreeParts tree{verts_, children_, ends_,
                 [this, depth](const JsonIn& child) { return parse_node(child, depth + 1); }};
  parse(j, n, tree);
  nodes_.push_back(n);
  return static_cast<uint32_t>(nodes_.size() - 1);
}

const char* ShapeTree::type_name(ShapeType type) {
  return kShapeParsers[static_cast<std::size_t>(type)].type.data();
}

Aabb ShapeTree::bounds_node(uint32_t i) const {
  const ShapeNode& n = nodes_[i];
  Aabb b;
  switch (n.type) {
    case ShapeType::kCircle:
      b.add(n.c - Vec2(n.r0, n.r0));
      b.add(n.c + Vec2(n.r0, n.r0));
      break;
    case ShapeType::kCapsule: {
      const Vec2 e = n.b.x() * Vec2(n.ca, n.sa), r(n.r0, n.r0);
      for (const Vec2& end : {Vec2(n.c - e), Vec2(n.c + e)}) {
        b.add(end - r);
        b.add(end + r);
      }
      break;
    }
    case ShapeType::kBox:
    case ShapeType::kRoundedBox: {
      const Vec2 h = n.b + Vec2(n.r0, n.r0);
      for (int k = 0; k < 4; ++k)
        b.add(n.c +
              Rotation{n.ca, n.sa}.apply(Vec2((k & 1) ? h.x() : -h.x(), (k & 2) ? h.y() : -h.y())));
      break;
    }
    case ShapeType::kTaperedCapsule:
      b.add(n.c - Vec2(n.r0, n.r0));
      b.add(n.c + Vec2(n.r0, n.r0));
      b.add(n.c + n.h * n.b - Vec2(n.r1, n.r1));
      b.add(n.c + n.h * n.b + Vec2(n.r1, n.r1));
      break;
    case ShapeType::kPolygon:
      for (uint32_t k = 0; k < n.count; ++k) b.add(verts_[n.first + k]);
      break;
    case ShapeType::kArc: {
      const double r = n.r0 + n.r1;
      b.add(n.c - Vec2(r, r));
      b.add(n.c + Vec2(r, r));
      break;
    }
    case ShapeType::kHalfPlane:
    case ShapeType::kInside:
      b = Aabb::everything();
      break;
    case ShapeType::kUnion:
      for (uint32_t k = 0; k < n.count; ++k) b.add(bounds_node(children_[n.first + k]));
      break;
    case ShapeType::kIntersection: {
      b = Aabb::everything();
      for (uint32_t k = 0; k < n.count; ++k) {
        const Aabb c = bounds_node(children_[n.first + k]);
        if (!c.bounded) continue;
        if (!b.bounded) {
          b = c;
        } else {
          b.lo = b.lo.cwiseMax(c.lo);
          b.hi = b.hi.cwiseMin(c.hi);
        }
      }
      break;
    }
    case ShapeType::kSubtraction:
      b = bounds_node(children_[n.first]);
      break;
  }
  return n.transformed ? transform_box(b, n.tf) : b;
}

Aabb ShapeTree::boundary_bounds() const {
  const ShapeNode& n = nodes_[root_];
  if (n.type == ShapeType::kInside) {
    const Aabb b = bounds_node(children_[n.first]);
    return n.transformed ? transform_box(b, n.tf) : b;
  }
  return bounds();
}

std::size_t ShapeTree::primitives() const {
  std::size_t k = 0;
  for (const auto& n : nodes_)
    if (n.type < ShapeType::kUnion) ++k;
  return k;
}

ShapeTree::Reduced ShapeTree::reduce(const Vec2& c, double radius) const {
  Reduced r{root_, false};
  const double m = 2.0 * radius;
  for (;;) {
    const ShapeNode& n = nodes_[r.node];
    if (n.transformed || n.type < ShapeType::kUnion) return r;
    const uint32_t* ch = children_.data() + n.first;
    if (n.type == ShapeType::kInside) {
      r = {ch[0], !r.neg};
      continue;
    }
    // operand values at c: children, negated after the first in a subtraction
    const bool sub = n.type == ShapeType::kSubtraction;
    const bool take_max = n.type != ShapeType::kUnion;
    uint32_t win = n.count;
    for (uint32_t k = 0; k < n.count && win == n.count; ++k) {
      const double fk = (sub && k > 0 ? -1.0 : 1.0) * eval_node<false>(ch[k], c).d;
      bool wins = true;
      for (uint32_t j = 0; j < n.count && wins; ++j) {
        if (j == k) continue;
        const double fj = (sub && j > 0 ? -1.0 : 1.0) * eval_node<false>(ch[j], c).d;
        wins = take_max ? fk - m > fj : fk + m < fj;
      }
      if (wins) win = k;
    }
    if (win == n.count) return r;
    r = {ch[win], sub && win > 0 ? !r.neg : r.neg};
  }
}

// Bounds of f along P(s) = a + s (b - a), s in [0, 1], from f and its gradient g at both
// ends. A convex f lies above its tangents, f(s) >= f(a) + s g_a.D and
// f(s) >= f(b) - (1 - s) g_b.D, and below its chord, so max f = max(f(a), f(b)); the lower
// bound is the least value of the larger tangent. Any exact SDF is 1-Lipschitz:
// f(s) >= (f(a) + f(b) - |D|) / 2 over the segment. Union is min, intersection max,
// containers and subtracted shapes negate (lower and upper bounds swap).
std::pair<double, double> ShapeTree::segment_node(uint32_t i, const Vec2& aw,
                                                  const Vec2& bw) const {
  using namespace eval_detail;
  const ShapeNode& n = nodes_[i];
  const Vec2 a = n.transformed ? n.tf.apply_inverse(aw) : aw;
  const Vec2 b = n.transformed ? n.tf.apply_inverse(bw) : bw;
  switch (n.type) {
    case ShapeType::kUnion:
    case ShapeType::kIntersection: {
      const bool uni = n.type == ShapeType::kUnion;
      std::pair<double, double> out{0.0, 0.0};
      for (uint32_t k = 0; k < n.count; ++k) {
        const auto c = segment_node(children_[n.first + k], a, b);
        if (k == 0)
          out = c;
        else if (uni)
          out = {std::min(out.first, c.first), std::min(out.second, c.second)};
        else
          out = {std::max(out.first, c.first), std::max(out.second, c.second)};
      }
      return out;
    }
    case ShapeType::kSubtraction: {
      auto out = segment_node(children_[n.first], a, b);
      for (uint32_t k = 1; k < n.count; ++k) {
        const auto c = segment_node(children_[n.first + k], a, b);
        out = {std::max(out.first, -c.second), std::max(out.second, -c.first)};
      }
      return out;
    }
    case ShapeType::kInside: {
      const auto c = segment_node(children_[n.first], a, b);
      return {-c.second, -c.first};
    }
    default:
      break;
  }
  const Sdf fa = eval_primitive<true>(n, a), fb = eval_primitive<true>(n, b);
  const Vec2 dab = b - a;
  const double len = dab.norm();
  const double lo_lip = 0.5 * (fa.d + fb.d - len), hi_lip = 0.5 * (fa.d + fb.d + len);
  const bool convex = n.type == ShapeType::kCircle || n.type == ShapeType::kBox ||
                      n.type == ShapeType::kRoundedBox || n.type == ShapeType::kCapsule ||
                      n.type == ShapeType::kTaperedCapsule ||
                      (n.type == ShapeType::kPolygon && n.count == 3);
  if (n.type == ShapeType::kHalfPlane) return {std::min(fa.d, fb.d), std::max(fa.d, fb.d)};
  if (!convex) return {lo_lip, hi_lip};
  const double sa = fa.g.dot(dab), sb = fb.g.dot(dab);
  double lo = 0.0;
  if (sa >= 0.0) {
    lo = fa.d;
  } else if (sb <= 0.0) {
    lo = fb.d;
  } else {  // the tangents cross at s = (f(a) - f(b) + g_b.D) / (g_b.D - g_a.D)
    const double s = std::clamp((fa.d - fb.d + sb) / (sb - sa), 0.0, 1.0);
    lo = fa.d + sa * s;
  }
  return {std::max(lo, lo_lip), std::min(std::max(fa.d, fb.d), hi_lip)};
}

}  // namespace pinsim::sdf
