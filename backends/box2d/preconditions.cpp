#include "preconditions.hpp"

#include <cmath>
#include <numbers>
#include <sstream>

namespace pinsim::box2d {
namespace {

std::string show(double x) {
  std::ostringstream o;
  o.precision(4);
  o << x;
  return o.str();
}

bool in_float_range(double x) { return x >= 1.0 / kMaxFloatValue && x <= kMaxFloatValue; }

}  // namespace

std::string coordinate_problem(double x, double y) {
  if (std::abs(x) <= kMaxUnits && std::abs(y) <= kMaxUnits) return "";
  // (appended piece by piece: GCC 12 warns wrongly of overlap in "literal" + string)
  std::string out = "(";
  out.append(show(x)).append(", ").append(show(y)).append(") Box2D units is beyond the limit of ");
  return out.append(show(kMaxUnits)).append(" (float rounding would exceed b2_linearSlop / 8)");
}

// The steps of b2PolygonShape::Set (Box2D 2.4.1, src/collision/b2_polygon_shape.cpp), with
// its float operations in the same order, stopping where it would assert.
std::string polygon_problem(const b2Vec2* vertices, int count) {
  if (count < 3 || count > b2_maxPolygonVertices)
    return std::to_string(count) + " vertices (Box2D polygons have 3 to " +
           std::to_string(b2_maxPolygonVertices) + ")";
  b2Vec2 ps[b2_maxPolygonVertices];
  int n = 0;
  for (int i = 0; i < count; ++i) {
    if (!vertices[i].IsValid()) return "a vertex is not a finite float";
    bool unique = true;
    for (int j = 0; j < n; ++j)
      if (b2DistanceSquared(vertices[i], ps[j]) <
          ((0.5f * b2_linearSlop) * (0.5f * b2_linearSlop))) {
        unique = false;
        break;
      }
    if (unique) ps[n++] = vertices[i];
  }
  const std::string degenerate =
      "degenerate for Box2D: its vertices, welded within b2_linearSlop / 2 = " +
      show(0.5 * b2_linearSlop) + " units, ";
  if (n < 3) return degenerate + "leave fewer than 3";
  int i0 = 0;
  float x0 = ps[0].x;
  for (int i = 1; i < n; ++i)
    if (ps[i].x > x0 || (ps[i].x == x0 && ps[i].y < ps[i0].y)) {
      i0 = i;
      x0 = ps[i].x;
    }
  int hull[b2_maxPolygonVertices];
  int m = 0, ih = i0;
  for (;;) {
    if (m >= b2_maxPolygonVertices) return degenerate + "give no closed convex hull";
    hull[m] = ih;
    int ie = 0;
    for (int j = 1; j < n; ++j) {
      if (ie == ih) {
        ie = j;
        continue;
      }
      const b2Vec2 r = ps[ie] - ps[hull[m]];
      const b2Vec2 v = ps[j] - ps[hull[m]];
      const float c = b2Cross(r, v);
      if (c < 0.0f) ie = j;
      if (c == 0.0f && v.LengthSquared() > r.LengthSquared()) ie = j;
    }
    ++m;
    ih = ie;
    if (ie == i0) break;
  }
  if (m < 3) return degenerate + "are collinear";
  b2Vec2 hv[b2_maxPolygonVertices];
  for (int i = 0; i < m; ++i) hv[i] = ps[hull[i]];
  for (int i = 0; i < m; ++i) {
    const b2Vec2 edge = hv[i + 1 < m ? i + 1 : 0] - hv[i];
    if (!(edge.LengthSquared() > b2_epsilon * b2_epsilon))
      return degenerate + "have a zero-length edge";
  }
  // ComputeCentroid's area
  const b2Vec2 s = hv[0];
  float area = 0.0f;
  for (int i = 0; i < m; ++i) {
    const b2Vec2 p1 = hv[0] - s;
    const b2Vec2 p2 = hv[i] - s;
    const b2Vec2 p3 = i + 1 < m ? hv[i + 1] - s : hv[0] - s;
    area += 0.5f * b2Cross(p2 - p1, p3 - p1);
  }
  if (!(area > b2_epsilon))
    return "degenerate for Box2D: area " + show(area) + " square units, not above b2_epsilon";
  return "";
}

std::string chain_problem(const std::vector<b2Vec2>& v, bool loop) {
  const std::size_t need = loop ? 3 : 2;
  if (v.size() < need)
    return std::to_string(v.size()) + " vertices (a Box2D chain " +
           (loop ? std::string("loop needs 3") : std::string("needs 2")) + ")";
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!v[i].IsValid()) return "a vertex is not a finite float";
    if (!loop && i == 0) continue;
    const b2Vec2& a = v[i == 0 ? v.size() - 1 : i - 1];
    if (!(b2DistanceSquared(a, v[i]) > b2_linearSlop * b2_linearSlop))
      return "vertices " + std::to_string(i == 0 ? v.size() - 1 : i - 1) + " and " +
             std::to_string(i) +
             " are not farther apart than b2_linearSlop = " + show(b2_linearSlop) + " units";
  }
  return "";
}

std::string particle_mass_problem(double m, double rs, bool rotates) {
  const double density = m / (std::numbers::pi * rs * rs);
  const double inertia = 0.5 * m * rs * rs;
  auto range = [] {
    return " is outside the range Box2D's float can use, [" + show(1.0 / kMaxFloatValue) + ", " +
           show(kMaxFloatValue) + "]";
  };
  if (!in_float_range(m)) return "mass " + show(m) + range();
  if (!in_float_range(density)) return "density " + show(density) + " per square unit" + range();
  if (rotates && !in_float_range(inertia)) return "rotational inertia " + show(inertia) + range();
  return "";
}

}  // namespace pinsim::box2d
