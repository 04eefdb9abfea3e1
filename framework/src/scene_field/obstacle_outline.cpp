// ObstacleField's outlines: each obstacle's boundary rings at a time, its bounds then and
// over every pose its motion can take, for a backend's outline() (pictures, view bounds).
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <pinsim/scene_field/obstacle_field.hpp>

namespace pinsim::sdf {
namespace {

void add_rings(Aabb& b, const std::vector<Ring>& rings) {
  for (const Ring& r : rings)
    for (const Vec2& p : r) b.add(p);
}

pinsim_bounds to_bounds(const Aabb& b) {
  if (!b.bounded || b.empty()) return empty_bounds();
  return {b.lo.x(), b.lo.y(), b.hi.x(), b.hi.y()};
}

// A rotating point p (about the pivot, at angles in [lo, hi]) reaches its extreme x or y
// where its direction phi + theta is a multiple of pi / 2 inside the range; the swept
// bounds are the two end poses plus those axis points.
void add_swept(Aabb& b, const Vec2& pivot, const Vec2& p, double lo, double hi) {
  b.add(pivot + Rotation::from_angle(lo).apply(p));
  b.add(pivot + Rotation::from_angle(hi).apply(p));
  const double rho = p.norm();
  if (!(rho > 0.0)) return;
  const double phi = std::atan2(p.y(), p.x());
  constexpr double kQuarter = 0.5 * std::numbers::pi, kTurn = 2.0 * std::numbers::pi;
  const std::array<Vec2, 4> axis = {Vec2(1.0, 0.0), Vec2(0.0, 1.0), Vec2(-1.0, 0.0),
                                    Vec2(0.0, -1.0)};
  for (int m = 0; m < 4; ++m) {
    double theta = m * kQuarter - phi;                  // the rotation that points p along axis m
    theta -= kTurn * std::floor((theta - lo) / kTurn);  // the first such angle >= lo
    if (theta < hi) b.add(pivot + rho * axis[m]);
  }
}

}  // namespace

Aabb ObstacleField::finite_bounds() const {
  Aabb region;
  for (const Obstacle& o : obs_) {
    if (o.motion == MotionType::kFlipper) {
      region.add(o.pivot - Vec2(o.reach, o.reach));
      region.add(o.pivot + Vec2(o.reach, o.reach));
    } else if (o.motion == MotionType::kSlider) {
      region.add(o.sweep);
    } else {
      const Aabb b = o.shape.boundary_bounds();
      if (b.bounded) region.add(b);
    }
  }
  return region;
}

double ObstacleField::default_outline_tolerance() const {
  const Aabb b = finite_bounds();
  if (b.empty()) return 1e-3;
  const double size = std::max(b.hi.x() - b.lo.x(), b.hi.y() - b.lo.y());
  return size > 0.0 ? 1e-3 * size : 1e-3;
}

Ring ObstacleField::outline_clip(const std::vector<Vec2>& extra) const {
  Aabb b = finite_bounds();
  for (const Vec2& p : extra) b.add(p);
  std::vector<Vec2> anchors;
  for (uint32_t k : static_) obs_[k].shape.add_half_plane_points(anchors);
  for (const Vec2& p : anchors) b.add(p);
  if (b.empty()) b = Aabb{Vec2(-1.0, -1.0), Vec2(1.0, 1.0), true};
  const double size = std::max(b.hi.x() - b.lo.x(), b.hi.y() - b.lo.y());
  const double pad = size > 0.0 ? 0.1 * size : 1.0;
  const Vec2 lo = b.lo - Vec2(pad, pad), hi = b.hi + Vec2(pad, pad);
  return {lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y())};
}

ObstacleField::Outline ObstacleField::outline(std::size_t k, double t, double tol,
                                              const Ring& clip) const {
  const Obstacle& o = obs_[k];
  Outline out;
  const std::vector<Ring> local = o.shape.outline(tol, clip).rings;
  switch (o.motion) {
    case MotionType::kStatic:
      out.rings = local;
      add_rings(out.bounds, out.rings);
      out.sweep = out.bounds;
      break;
    case MotionType::kFlipper: {
      double c = 1.0, s = 0.0;
      o.timeline->value_cos_sin(t, c, s);
      const Rotation at{c, s};
      for (const Ring& r : local) {
        Ring w;
        for (const Vec2& p : r) {
          w.push_back(o.pivot + at.apply(p));
          add_swept(out.sweep, o.pivot, p, o.timeline->lo(), o.timeline->hi());
        }
        out.rings.push_back(std::move(w));
      }
      add_rings(out.bounds, out.rings);
      break;
    }
    case MotionType::kSlider: {
      const double lambda = o.timeline->value(t);
      for (const Ring& r : local) {
        Ring w;
        for (const Vec2& p : r) {
          w.push_back(p + lambda * o.offset);
          out.sweep.add(p + o.timeline->lo() * o.offset);
          out.sweep.add(p + o.timeline->hi() * o.offset);
        }
        out.rings.push_back(std::move(w));
      }
      add_rings(out.bounds, out.rings);
      break;
    }
  }
  return out;
}

OutlineSet outline_set(const ObstacleField& field, const StateView& s, double tolerance) {
  std::vector<Vec2> particles;
  for (std::size_t i = 0; i < s.n; ++i) particles.push_back(s.x.col(static_cast<Eigen::Index>(i)));
  const Ring clip = field.outline_clip(particles);
  const double tol = tolerance > 0.0 ? tolerance : field.default_outline_tolerance();
  OutlineSet set;
  for (std::size_t k = 0; k < field.size(); ++k) {
    const ObstacleField::Outline o = field.outline(k, s.t, tol, clip);
    ObstacleOutline out;
    out.obstacle = static_cast<int64_t>(k);
    out.id = field.obstacle(k).id;
    out.bounds = to_bounds(o.bounds);
    out.sweep = to_bounds(o.sweep);
    out.rings = o.rings;
    add_bounds(set.bounds, out.bounds);
    add_bounds(set.sweep, out.sweep);
    set.obstacles.push_back(std::move(out));
  }
  return set;
}

}  // namespace pinsim::sdf
