// Rings: an obstacle's boundary as closed polylines (for pictures and view bounds), and the
// boolean operations that combine them the way the SDF tree combines distances.
#pragma once

#include <pinsim/plugin.hpp>
#include <vector>

namespace pinsim::sdf {

/// The z component of a x b (twice the signed area of the triangle 0, a, b).
inline double cross(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

/// A closed polyline (the last point joins the first; it is not repeated).
using Ring = std::vector<Vec2>;

/// A solid given by its boundary rings: p is in the solid if it lies inside an odd number of
/// rings, or, if `complement` (the solid is the unbounded outside of the rings), an even
/// number. Rings run with the solid on their left (counter-clockwise around a bounded part).
struct Rings {
  std::vector<Ring> rings;
  bool complement = false;
  /// Even-odd test, flipped if complement.
  bool contains(const Vec2& p) const;
};

/// How the parts of an SDF tree node combine.
enum class RingOp { kUnion, kIntersection, kSubtraction };

/// The boundary of the union, intersection or subtraction (the first part minus the others)
/// of `parts`: every edge is split where it crosses another part's edges, the pieces whose
/// midpoints lie on the wrong side of the other parts are dropped, and the rest are chained
/// end to start into closed rings.
Rings combine(const std::vector<Rings>& parts, RingOp op);

/// Appends the arc of radius r about c from angle a0 to a1 (a1 >= a0, rad): both ends, as
/// many points between as keep the chord within `tol` of the arc, evenly spaced, and the
/// points where the arc points along a world axis (angle + `frame` a multiple of pi / 2,
/// `frame` being the angle of this frame in the world), so that bounds are exact.
void add_arc(Ring& out, const Vec2& c, double r, double a0, double a1, double tol, double frame);

/// The full circle of radius r about c, counter-clockwise, with a multiple of four points
/// starting where it points along the world's x axis (angle -`frame`), so that its extreme
/// points (c +- r along each world axis) are vertices.
Ring circle_ring(const Vec2& c, double r, double tol, double frame);

/// The part of the convex polygon `poly` where (p - point).normal <= 0 (Sutherland-Hodgman).
Ring clip_half_plane(const Ring& poly, const Vec2& point, const Vec2& normal);

}  // namespace pinsim::sdf
