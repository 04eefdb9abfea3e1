// ShapeTree: one obstacle's 2D signed distance field, compiled from its "shape" JSON.
#pragma once

#include <cstdint>
#include <pinsim/plugin.hpp>
#include <pinsim/scene_field/json_in.hpp>
#include <pinsim/scene_field/outline.hpp>
#include <pinsim/transform.hpp>
#include <utility>
#include <vector>

namespace pinsim::sdf {

/// A signed distance and its gradient (unit length; the outward normal at the surface).
struct Sdf {
  double d = HUGE_VAL;
  Vec2 g{0.0, 1.0};
};

/// An axis-aligned box; `bounded == false` means the whole plane.
struct Aabb {
  Vec2 lo{HUGE_VAL, HUGE_VAL};
  Vec2 hi{-HUGE_VAL, -HUGE_VAL};
  bool bounded = true;

  static Aabb everything() {
    Aabb b;
    b.bounded = false;
    return b;
  }
  bool empty() const { return bounded && (lo.x() > hi.x() || lo.y() > hi.y()); }
  void add(const Vec2& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void add(const Aabb& b) {
    if (!b.bounded) bounded = false;
    if (b.bounded && !b.empty()) {
      add(b.lo);
      add(b.hi);
    }
  }
  /// Distance from p to the box (0 inside); 0 when unbounded.
  double distance(const Vec2& p) const {
    if (!bounded) return 0.0;
    const Vec2 q = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
    return q.norm();
  }
};

/// Order matters: the first four (up to kCapsule) share eval_box, primitives come before
/// kUnion, and ShapeTree tests both by comparison.
enum class ShapeType : uint8_t {
  kCircle,
  kBox,
  kRoundedBox,
  kCapsule,
  kTaperedCapsule,
  kPolygon,
  kArc,
  kHalfPlane,
  kUnion,
  kIntersection,
  kSubtraction,
  kInside
};

/// One node of the tree. Primitive parameters are stored in the node's own frame.
struct ShapeNode {
  ShapeType type = ShapeType::kCircle;
  bool transformed = false;
  Transform tf;               ///< the node's transform: world = tf.apply(local)
  Vec2 c{0.0, 0.0};           ///< centre (circle, box, capsule midpoint) / a / point
  Vec2 b{0.0, 0.0};           ///< half size (capsule: (length / 2, 0)) / axis / normal
  double ca = 1.0, sa = 0.0;  ///< primitive orientation (box angle, arc middle, capsule axis)
  double r0 = 0.0, r1 = 0.0;  ///< radius / corner radius / radius_a, radius_b / arc half-thickness
  double h = 0.0;             ///< tapered capsule length; arc: sin of half aperture in r1...
  double k0 = 0.0, k1 = 0.0;  ///< precomputed constants (arc sin/cos, tapered a/b)
  uint32_t first = 0, count = 0;  ///< children (children_), polygon vertices (verts_) or,
                                  ///< capsules, the ends as given (ends_[first])
};

class ShapeTree {
 public:
  ShapeTree() = default;
  /// Compiles `j` (a "shape" object); throws pinsim::Error with the JSON path on bad input.
  static ShapeTree parse(const JsonIn& j);

  /// Signed distance at p (shape frame); with G, also the gradient.
  template <bool G>
  Sdf eval(const Vec2& p) const {
    // most obstacles are one untransformed primitive: skip the tree walk
    return root_primitive_ ? eval_primitive<G>(nodes_[root_], p) : eval_node<G>(root_, p);
  }
  /// A node and a sign whose evaluation, negated if `neg`, equals the whole tree's to the
  /// bit everywhere within `radius` of c: found by descending through containers and
  /// through untransformed unions, intersections and subtractions one of whose operands
  /// wins by more than 2 radius at c (all nodes are 1-Lipschitz, so it wins over the disc).
  struct Reduced {
    uint32_t node = 0;
    bool neg = false;
  };
  Reduced reduce(const Vec2& c, double radius) const;
  /// Evaluation of a reduced tree: eval_node(node), negated if neg.
  template <bool G>
  [[gnu::always_inline]] Sdf eval_reduced(uint32_t node, bool neg, const Vec2& p) const {
    const ShapeNode& n = nodes_[node];
    Sdf s = n.type <= ShapeType::kCapsule && !n.transformed ? eval_box<G>(n, p)
            : n.type < ShapeType::kUnion && !n.transformed  ? eval_primitive<G>(n, p)
                                                            : eval_node<G>(node, p);
    // times +-1 rather than a branch: random queries would mispredict it (same bits as -x)
    const double sign = neg ? -1.0 : 1.0;
    s.d *= sign;
    if constexpr (G) s.g *= sign;
    return s;
  }
  /// Lower and upper bounds of the signed distance over the segment from a to b (shape
  /// frame), from the values and gradients at the two ends: exact for half-planes, by
  /// convexity for convex primitives (the SDF of a convex set is convex), by the Lipschitz
  /// bound otherwise; combined through the tree as min / max / negation.
  std::pair<double, double> segment_bounds(const Vec2& a, const Vec2& b) const {
    return segment_node(root_, a, b);
  }
  /// Bounds of the solid in the shape frame (unbounded for half-planes and containers).
  Aabb bounds() const { return bounds_node(root_); }
  /// Bounds of the boundary curve (a container's inner shape); unbounded if none.
  Aabb boundary_bounds() const;
  /// Number of primitives (leaves).
  std::size_t primitives() const;

  // The compiled tree, read-only, for builders of other representations of the same
  // description (the box2d backend's fixtures), so that the scene's shapes have one reader.
  /// The root node's index.
  uint32_t root() const { return root_; }
  /// Node i.
  const ShapeNode& node(uint32_t i) const { return nodes_[i]; }
  /// The index of child k of a union, intersection, subtraction or inside node.
  uint32_t child(const ShapeNode& n, uint32_t k) const { return children_[n.first + k]; }
  /// A polygon node's vertices, counter-clockwise (the scene's order, reversed if clockwise).
  std::vector<Vec2> polygon(const ShapeNode& n) const {
    return {verts_.begin() + n.first, verts_.begin() + n.first + n.count};
  }
  /// A capsule's or tapered capsule's ends a and b, as the scene gave them.
  const std::pair<Vec2, Vec2>& ends(const ShapeNode& n) const { return ends_[n.first]; }
  /// The scene's name of a shape type ("circle", "rounded_box", ...).
  static const char* type_name(ShapeType type);
  /// The boundary as closed rings in the shape frame (see shape_outline.cpp): arcs within
  /// `tol` of the exact curve, half-planes cut to the convex polygon `clip` (shape frame).
  Rings outline(double tol, const Ring& clip) const;
  /// Adds the point of every half-plane in the tree (shape frame): where the unbounded
  /// parts are anchored, so that the rectangle they are cut to reaches them.
  void add_half_plane_points(std::vector<Vec2>& out) const { add_points_node(root_, {}, out); }

 private:
  uint32_t parse_node(const JsonIn& j, int depth);
  template <bool G>
  Sdf eval_node(uint32_t i, const Vec2& p) const;
  template <bool G>
  Sdf eval_primitive(const ShapeNode& n, const Vec2& p) const;
  template <bool G>
  static Sdf eval_box(const ShapeNode& n, const Vec2& p);
  Aabb bounds_node(uint32_t i) const;
  Rings outline_node(uint32_t i, double tol, const Ring& clip, double frame) const;
  void add_points_node(uint32_t i, const Transform& parent, std::vector<Vec2>& out) const;
  std::pair<double, double> segment_node(uint32_t i, const Vec2& a, const Vec2& b) const;

  std::vector<ShapeNode> nodes_;
  std::vector<uint32_t> children_;
  std::vector<Vec2> verts_;
  std::vector<std::pair<Vec2, Vec2>> ends_;
  uint32_t root_ = 0;
  bool root_primitive_ = false;  ///< root is a primitive without a transform
};

}  // namespace pinsim::sdf

#include <pinsim/scene_field/shape_eval.inl>
