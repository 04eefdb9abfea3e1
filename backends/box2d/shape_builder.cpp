#include "shape_builder.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace pinsim::box2d {
namespace {

using sdf::cross;

double signed_area2(const std::vector<Vec2>& v) {
  double a = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) a += cross(v[i], v[(i + 1) % v.size()]);
  return a;
}

/// Drops vertices lying on the line through their neighbours (they add nothing).
std::vector<Vec2> drop_collinear(const std::vector<Vec2>& v) {
  std::vector<Vec2> out;
  const std::size_t n = v.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2& a = v[(i + n - 1) % n];
    const Vec2& b = v[i];
    const Vec2& c = v[(i + 1) % n];
    const double scale = (b - a).norm() * (c - b).norm();
    if (std::abs(cross(b - a, c - b)) > 1e-12 * scale) out.push_back(b);
  }
  return out;
}

bool point_in_triangle(const Vec2& p, const Vec2& a, const Vec2& b, const Vec2& c) {
  return cross(b - a, p - a) >= 0.0 && cross(c - b, p - b) >= 0.0 && cross(a - c, p - c) >= 0.0;
}

/// Even-odd point-in-polygon test.
bool point_in_polygon(const Vec2& p, const std::vector<Vec2>& v) {
  bool in = false;
  for (std::size_t i = 0, j = v.size() - 1; i < v.size(); j = i++) {
    if ((v[i].y() > p.y()) != (v[j].y() > p.y())) {
      const double x =
          v[j].x() + (p.y() - v[j].y()) / (v[i].y() - v[j].y()) * (v[i].x() - v[j].x());
      if (p.x() < x) in = !in;
    }
  }
  return in;
}

class Builder {
 public:
  Builder(const sdf::ShapeTree& tree, std::string ctx, std::string id, const BuildOptions& opt)
      : tree_(tree), ctx_(std::move(ctx)), id_(std::move(id)), opt_(opt) {}

  [[noreturn]] void unsupported(const std::string& path, const std::string& what) const {
    throw Error(ctx_ + ": " + path + ": unsupported by box2d (obstacle '" + id_ + "'): " + what);
  }

  /// The node's own transform (the identity if it has none).
  static Transform node_xform(const sdf::ShapeNode& n) {
    return n.transformed ? n.tf : Transform{};
  }
  /// The path of shape k below `path` (a union's "shapes").
  static std::string shapes_path(const std::string& path, uint32_t k) {
    return path + ".shapes[" + std::to_string(k) + "]";
  }

  /// Corners of a box (counter-clockwise) in the parent frame.
  static std::vector<Vec2> box_corners(const Transform& x, const Vec2& c, const Vec2& h,
                                       const Rotation& box) {
    std::vector<Vec2> out;
    for (const Vec2& q :
         {Vec2(-h.x(), -h.y()), Vec2(h.x(), -h.y()), Vec2(h.x(), h.y()), Vec2(-h.x(), h.y())})
      out.push_back(x.apply(c + box.apply(q)));
    return out;
  }

  void polygon(const std::vector<Vec2>& pts, double radius, const std::string& path) {
    std::vector<Vec2> v = pts;
    if (signed_area2(v) < 0.0) std::reverse(v.begin(), v.end());
    v = drop_collinear(v);
    if (v.size() < 3) unsupported(path, "degenerate polygon");
    std::vector<std::vector<Vec2>> parts;
    if (is_convex(v) && v.size() <= 8)
      parts.push_back(v);
    else
      parts = convex_decompose(v, 8);
    for (auto& p : parts) {
      Piece pc;
      pc.kind = Piece::Kind::kPolygon;
      pc.v = std::move(p);
      pc.radius = radius;
      out.push_back(std::move(pc));
    }
  }

  void circle(const Vec2& c, double r) {
    Piece p;
    p.kind = Piece::Kind::kCircle;
    p.v = {c};
    p.radius = r;
    out.push_back(p);
  }

  void edge(const Vec2& a, const Vec2& b, double r) {
    Piece p;
    p.kind = Piece::Kind::kEdge;
    p.v = {a, b};
    p.radius = r;
    out.push_back(p);
  }

  /// A solid shape (not a container), transform `x` already includes the node's own.
  void solid(uint32_t i, const Transform& parent, const std::string& path) {
    using sdf::ShapeType;
    const sdf::ShapeNode& n = tree_.node(i);
    const Transform x = parent.compose(node_xform(n));
    const Rotation orient{n.ca, n.sa};
    if (n.type == ShapeType::kCircle) {
      circle(x.apply(n.c), n.r0);
    } else if (n.type == ShapeType::kBox) {
      polygon(box_corners(x, n.c, n.b, orient), 0.0, path);
    } else if (n.type == ShapeType::kRoundedBox) {
      // Box2D polygons carry a rounding radius: the inner box (half size minus the corner
      // radius) plus radius corner_radius is exactly the rounded box.
      const double cr = n.r0;
      const Vec2 h = n.b;
      if (!(h.x() > 0.0 && h.y() > 0.0))
        unsupported(path,
                    "rounded_box with corner_radius = min(half_size) is a capsule or disc; "
                    "write it as one");
      polygon(box_corners(x, n.c, h, orient), cr, path);
    } else if (n.type == ShapeType::kCapsule) {
      // An edge with rounding radius r is exactly the capsule (radius 0: a two-sided wall).
      const Vec2 a = x.apply(tree_.ends(n).first), b = x.apply(tree_.ends(n).second);
      const double r = n.r0;
      if ((b - a).norm() == 0.0) {
        if (r > 0.0)
          circle(a, r);
        else
          unsupported(path, "capsule of zero length and zero radius is a point");
      } else {
        edge(a, b, r);
      }
    } else if (n.type == ShapeType::kTaperedCapsule) {
      // Two discs and the quad between their outer tangent points (iq's uneven capsule:
      // side normal (k1, k0) in the frame x across, y along a->b, k0 = (ra - rb)/h).
      const Vec2 a = x.apply(tree_.ends(n).first), b = x.apply(tree_.ends(n).second);
      const double ra = n.r0, rb = n.r1;
      const double h = (b - a).norm();
      const Vec2 ey = (b - a) / h, ex(ey.y(), -ey.x());
      const double k0 = (ra - rb) / h, k1 = std::sqrt(1.0 - k0 * k0);
      const Vec2 n1 = k1 * ex + k0 * ey, n2 = -k1 * ex + k0 * ey;
      if (ra > 0.0) circle(a, ra);
      if (rb > 0.0) circle(b, rb);
      std::vector<Vec2> quad = {a + ra * n1, b + rb * n1, b + rb * n2, a + ra * n2};
      if (ra == 0.0 && rb == 0.0) {
        edge(a, b, 0.0);
      } else if (ra == 0.0 || rb == 0.0) {
        quad = ra == 0.0 ? std::vector<Vec2>{a, b + rb * n1, b + rb * n2}
                         : std::vector<Vec2>{a + ra * n1, b, a + ra * n2};
        polygon(quad, 0.0, path);
      } else {
        polygon(quad, 0.0, path);
      }
    } else if (n.type == ShapeType::kPolygon) {
      std::vector<Vec2> pts;
      for (const Vec2& p : tree_.polygon(n)) pts.push_back(x.apply(p));
      polygon(pts, 0.0, path);
    } else if (n.type == ShapeType::kHalfPlane) {
      // A long one-sided edge, colliding on the normal's side (Box2D: right of a->b).
      const Vec2 normal = x.r.apply(n.b);  // the unit normal (the reader normalized it)
      const Vec2 p0 = x.apply(n.c);
      const Vec2 along(-normal.y(), normal.x());
      const Vec2 foot = p0 + along * along.dot(opt_.centre - p0);
      const double L = opt_.half_plane_extent;
      Piece p;
      p.kind = Piece::Kind::kEdge;
      p.v = {foot + L * along, foot - L * along};  // right of a->b = n
      p.one_sided = true;
      out.push_back(p);
    } else if (n.type == ShapeType::kUnion) {
      for (uint32_t k = 0; k < n.count; ++k) solid(tree_.child(n, k), x, shapes_path(path, k));
    } else if (n.type == ShapeType::kInside) {
      container(tree_.child(n, 0), x, path + ".shape");
    } else if (n.type == ShapeType::kArc) {
      unsupported(path,
                  "an arc is a curved band with a concave side; Box2D 2.4.1 has no "
                  "curved shape but the circle");
    } else if (n.type == ShapeType::kIntersection) {
      unsupported(path,
                  "an intersection (max of SDFs) is not a set of Box2D fixtures; write "
                  "the resulting shape as a polygon");
    } else {  // ShapeType::kSubtraction
      unsupported(path,
                  "a subtraction leaves a boundary Box2D fixtures cannot express (concave "
                  "and curved where a curved shape is removed); write the result as a "
                  "polygon");
    }
  }

  /// Closed counter-clockwise outline of a leaf of a container's shape.
  void outline(uint32_t i, const Transform& parent, const std::string& path,
               std::vector<std::vector<Vec2>>& loops) {
    using sdf::ShapeType;
    const sdf::ShapeNode& node = tree_.node(i);
    const Transform x = parent.compose(node_xform(node));
    if (node.type == ShapeType::kUnion) {
      for (uint32_t k = 0; k < node.count; ++k)
        outline(tree_.child(node, k), x, shapes_path(path, k), loops);
    } else if (node.type == ShapeType::kBox) {
      loops.push_back(box_corners(x, node.c, node.b, Rotation{node.ca, node.sa}));
    } else if (node.type == ShapeType::kPolygon) {
      std::vector<Vec2> pts;
      for (const Vec2& p : tree_.polygon(node)) pts.push_back(x.apply(p));
      if (signed_area2(pts) < 0.0) std::reverse(pts.begin(), pts.end());
      loops.push_back(pts);
    } else if (node.type == ShapeType::kCircle) {
      if (opt_.curve_segments <= 0)
        unsupported(path,
                    "the inside of a circle is a concave curved wall; Box2D can only "
                    "approximate it by segments (set the box2d parameter curve_segments, "
                    "e.g. 256, to accept that approximation)");
      const Vec2 c = x.apply(node.c);
      const double r = node.r0;
      const int n = opt_.curve_segments;
      std::vector<Vec2> v;
      for (int k = 0; k < n; ++k) {
        const double a = 2.0 * std::numbers::pi * k / n;
        v.push_back(c + r * Vec2(std::cos(a), std::sin(a)));
      }
      loops.push_back(v);
    } else {
      unsupported(path, std::string("'inside' of a ") + sdf::ShapeTree::type_name(node.type) +
                            " (a container wall Box2D cannot express; supported: box, polygon, "
                            "circle with curve_segments, and unions of those)");
    }
  }

  /// The ball lives inside `j`: the boundary of the union of its leaves as chain loops,
  /// wound clockwise so that Box2D's one-sided chains collide from the inside.
  void container(uint32_t i, const Transform& x, const std::string& path) {
    std::vector<std::vector<Vec2>> loops;
    outline(i, x, path, loops);
    struct Seg {
      Vec2 a, b;
    };
    std::vector<Seg> kept;
    for (std::size_t k = 0; k < loops.size(); ++k) {
      const auto& L = loops[k];
      for (std::size_t i = 0; i < L.size(); ++i) {
        const Vec2 a = L[i], b = L[(i + 1) % L.size()];
        std::vector<double> ts = {0.0, 1.0};
        for (std::size_t m = 0; m < loops.size(); ++m) {
          if (m == k) continue;
          const auto& M = loops[m];
          for (std::size_t q = 0; q < M.size(); ++q) {
            const Vec2 c = M[q], d = M[(q + 1) % M.size()];
            const double den = cross(b - a, d - c);
            if (den == 0.0) continue;
            const double t = cross(c - a, d - c) / den, u = cross(c - a, b - a) / den;
            if (t > 1e-12 && t < 1.0 - 1e-12 && u >= 0.0 && u <= 1.0) ts.push_back(t);
          }
        }
        std::sort(ts.begin(), ts.end());
        for (std::size_t q = 0; q + 1 < ts.size(); ++q) {
          if (ts[q + 1] - ts[q] < 1e-12) continue;
          const Vec2 p0 = a + ts[q] * (b - a), p1 = a + ts[q + 1] * (b - a);
          const Vec2 mid = 0.5 * (p0 + p1);
          bool covered = false;
          for (std::size_t m = 0; m < loops.size() && !covered; ++m)
            covered = m != k && point_in_polygon(mid, loops[m]);
          if (!covered) kept.push_back({p0, p1});
        }
      }
    }
    // Chain the kept segments into closed loops by matching end points.
    double size = 0.0;
    for (const auto& s : kept)
      size = std::max({size, s.a.cwiseAbs().maxCoeff(), s.b.cwiseAbs().maxCoeff()});
    const double tol = 1e-9 * std::max(size, 1.0);
    std::vector<bool> used(kept.size(), false);
    for (std::size_t s0 = 0; s0 < kept.size(); ++s0) {
      if (used[s0]) continue;
      std::vector<Vec2> loop = {kept[s0].a};
      used[s0] = true;
      Vec2 end = kept[s0].b;
      while ((end - loop.front()).norm() > tol) {
        std::size_t next = kept.size();
        for (std::size_t s = 0; s < kept.size(); ++s)
          if (!used[s] && (kept[s].a - end).norm() <= tol) {
            next = s;
            break;
          }
        if (next == kept.size())
          unsupported(path,
                      "could not trace a closed boundary of this container (touching or "
                      "overlapping edges); write it as one polygon");
        used[next] = true;
        loop.push_back(kept[next].a);
        end = kept[next].b;
      }
      loop = drop_collinear(loop);
      if (loop.size() < 3) continue;
      std::reverse(loop.begin(), loop.end());  // clockwise: the inside is on the right
      Piece p;
      p.kind = Piece::Kind::kChainLoop;
      p.v = std::move(loop);
      out.push_back(std::move(p));
    }
  }

  std::vector<Piece> out;

 private:
  const sdf::ShapeTree& tree_;
  std::string ctx_, id_;
  BuildOptions opt_;
};

}  // namespace

bool is_convex(const std::vector<Vec2>& v) {
  const std::size_t n = v.size();
  for (std::size_t i = 0; i < n; ++i)
    if (cross(v[(i + 1) % n] - v[i], v[(i + 2) % n] - v[(i + 1) % n]) <= 0.0) return false;
  return true;
}

std::vector<std::vector<Vec2>> convex_decompose(const std::vector<Vec2>& ccw, int max_vertices) {
  // Ear clipping: an ear is a convex vertex whose triangle holds no other vertex.
  std::vector<std::size_t> idx(ccw.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  std::vector<std::vector<std::size_t>> tris;
  while (idx.size() > 3) {
    const std::size_t m = idx.size();
    bool clipped = false;
    for (std::size_t k = 0; k < m && !clipped; ++k) {
      const std::size_t ip = idx[(k + m - 1) % m], ic = idx[k], in = idx[(k + 1) % m];
      const Vec2 &a = ccw[ip], &b = ccw[ic], &c = ccw[in];
      if (cross(b - a, c - b) <= 0.0) continue;
      bool empty = true;
      for (std::size_t q = 0; q < m && empty; ++q) {
        const std::size_t iq = idx[q];
        if (iq == ip || iq == ic || iq == in) continue;
        empty = !point_in_triangle(ccw[iq], a, b, c);
      }
      if (!empty) continue;
      tris.push_back({ip, ic, in});
      idx.erase(idx.begin() + static_cast<std::ptrdiff_t>(k));
      clipped = true;
    }
    if (!clipped) {  // only degenerate (collinear) vertices left: clip the first one
      tris.push_back({idx[m - 1], idx[0], idx[1]});
      idx.erase(idx.begin());
    }
  }
  tris.push_back(idx);
  // Hertel-Mehlhorn: remove diagonals while the merged piece stays convex and small.
  std::vector<std::vector<std::size_t>> parts = tris;
  bool merged = true;
  while (merged) {
    merged = false;
    for (std::size_t p = 0; p < parts.size() && !merged; ++p) {
      for (std::size_t q = p + 1; q < parts.size() && !merged; ++q) {
        const auto &A = parts[p], &B = parts[q];
        for (std::size_t i = 0; i < A.size() && !merged; ++i) {
          const std::size_t u = A[i], w = A[(i + 1) % A.size()];
          for (std::size_t k = 0; k < B.size() && !merged; ++k) {
            if (B[k] != w || B[(k + 1) % B.size()] != u) continue;
            // A: ... u w ...; B: ... w u ...; merged: A from w round to u, then B after u to before
            // w
            std::vector<std::size_t> c;
            for (std::size_t s = 0; s < A.size(); ++s) c.push_back(A[(i + 1 + s) % A.size()]);
            for (std::size_t s = 2; s < B.size(); ++s) c.push_back(B[(k + s) % B.size()]);
            if (static_cast<int>(c.size()) > max_vertices) continue;
            std::vector<Vec2> cv;
            for (std::size_t s : c) cv.push_back(ccw[s]);
            if (!is_convex(cv)) continue;
            parts[p] = c;
            parts.erase(parts.begin() + static_cast<std::ptrdiff_t>(q));
            merged = true;
          }
        }
      }
    }
  }
  std::vector<std::vector<Vec2>> out;
  for (const auto& p : parts) {
    std::vector<Vec2> v;
    for (std::size_t s : p) v.push_back(ccw[s]);
    if (std::abs(signed_area2(v)) > 0.0) out.push_back(std::move(v));
  }
  return out;
}

std::vector<Piece> build_pieces(const sdf::ShapeTree& shape, const std::string& ctx,
                                const std::string& path, const std::string& id,
                                const BuildOptions& opt) {
  Builder b(shape, ctx, id, opt);
  b.solid(shape.root(), Transform{}, path);
  return std::move(b.out);
}

}  // namespace pinsim::box2d
