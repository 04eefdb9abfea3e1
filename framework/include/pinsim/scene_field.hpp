// pinsim/scene_field.hpp: the scene's obstacles as a signed distance field, for backends.
//
// Link the CMake target pinsim::scene_field (find_package(pinsim); in-tree
// pinsim_scene_field). It reads the backend's scene block (CreateContext::scene: its
// "obstacles" and "inputs"; the format is backends/sdf/README.md, "Scene format") into
// shapes (circle, box, rounded_box, capsule, tapered_capsule, polygon, arc, half_plane),
// booleans (union, intersection, subtraction, inside), transforms, materials and scripted
// motion (flippers, sliders driven by inputs), and answers, for any point p and time t:
//
//   field.nearest(p, t)                  phi(p, t) = min_k phi_k(p, t) and the nearest k
//   field.nearest_with_gradient(p, t)    the same with grad phi_k (the outward normal)
//   field.eval(k, p, t)                  phi_k and grad phi_k of obstacle k
//   field.velocity(k, p, t)              velocity of obstacle k's surface point at p
//   field.obstacle(k).material           restitution e, friction mu, kick (units/s)
//   field.obstacle(k).id, .motion        the scene's id; static, flipper or slider
//   field.input(name, pressed, t)        a live press or release (pinsim play)
//   field.outline(k, t, tol, clip)       the boundary as closed polylines, its bounds
//   outline_set(field, state, tol)       every outline, as a backend's outline() returns
//
// Scores are kept by the host's game (pinsim play), from the events a backend reports: an
// obstacle whose id contains "bumper" or "sling", or one with a kick, scores; one whose id
// contains "drain" ends the ball. A backend reports events and nothing more.
// Nothing here moves a particle: there is no time stepping, no marching and no impulse.
//
// Units: lengths in scene units (metres in the shipped tables), angles in radians
// (counter-clockwise from +x), times in seconds, speeds in units/s. Every number of an
// obstacle or input is at most kMaxMagnitude = 1e9 in magnitude (refused beyond it).
//
// Contract.
// - Sign: phi < 0 inside an obstacle's solid, 0 on its boundary, > 0 outside. phi is the
//   exact Euclidean distance for every primitive, so |phi(p) - phi(q)| <= |p - q|
//   (1-Lipschitz); booleans (min, max, max(d0, -d1, ...), -d) keep it 1-Lipschitz and
//   exact outside unions (a lower bound of the distance inside them): a disc of radius
//   phi(p) about p touches no solid, which is what sphere tracing relies on.
// - Gradient: grad phi has unit length everywhere and is the outward normal on the
//   boundary. It is analytic, not a finite difference. On a boolean seam (where two
//   operands of a union, intersection or subtraction have equal values) phi is not
//   differentiable; the gradient returned is the one-sided gradient of the operand that
//   wins the comparison, the first in the scene's order on an exact tie (union: the first
//   child with the least value; intersection: the first with the greatest; subtraction:
//   the first shape unless a subtracted one is strictly greater). At singular points of a
//   primitive (a circle's centre, a box's medial axis, a zero-thickness segment) the
//   choice is fixed and finite (backends/sdf/README.md, Gradients). The same rule holds
//   between obstacles: nearest() reports the obstacle of least phi, ties resolved the same
//   way every time (bit-identical runs).
// - Time: phi, grad phi and velocity are functions of the absolute time t (the state's
//   time, s.t, plus the time into the step). Flipper angles and slider positions are
//   piecewise linear in t, exact at any t, so a backend may query any time within its step
//   [s.t, s.t + dt], in any order, and must query at the time it means: the obstacle does
//   not move by itself between queries. A moving obstacle's field at a fixed point changes
//   at most as fast as its fastest point moves (speed_bound). Inputs: the scene's "inputs"
//   are on the timelines from the start; a live input (input()) is appended at the state
//   time between steps and the run continues as if the scene had listed it.
// - velocity(k, p, t) is omega x (p - pivot) for a flipper, lambda'(t) offset for a slider,
//   0 for a static obstacle; at a time where the motion starts or stops it is the rate of
//   the segment starting at or before t.
//
// For a backend, FieldBackend (below) is a base class that builds the field from the
// CreateContext and provides distance(), input() and outline(), so that pinsim run,
// validate, play, render, replay and share show the table: the backend writes only
// info(), its constructor and advance(). See sdk/pinball_starter/.
#pragma once

#include <cmath>
#include <pinsim/plugin.hpp>
#include <pinsim/scene_field/limits.hpp>
#include <pinsim/scene_field/obstacle_field.hpp>
#include <string>
#include <string_view>
#include <vector>

namespace pinsim::sdf {

/// The acceleration grid's default target cell count (the sdf backend's `grid_cells`).
inline constexpr long kDefaultGridCells = 16384;

/// Base class of a backend whose obstacles are the scene field: derive from it, call its
/// constructor from yours, and PINSIM_PLUGIN finds distance(), input() and outline() (the
/// capabilities PINSIM_CAP_DISTANCE, _INPUTS and _OUTLINES). A derived class that keeps
/// caches depending on the timelines may hide input() with its own that calls this one.
class FieldBackend {
 public:
  /// Signed distance from p to the nearest obstacle at time t (HUGE_VAL if there are none);
  /// its index in *obstacle (-1 if none) when obstacle is not null.
  double distance(const Vec2& p, double t, int64_t* obstacle) const {
    const Nearest n = field_.nearest(p, t);
    if (obstacle) *obstacle = n.k;
    return n.d;
  }
  /// Input `name` pressed or released at time t (at or after its last event), between
  /// steps. Throws Error naming an input no obstacle listens to.
  void input(const std::string& name, bool pressed, double t) { field_.input(name, pressed, t); }
  /// Each obstacle's boundary at s.t as closed polylines within `tolerance` (<= 0: 1e-3 of
  /// the obstacles' extent), with its bounds then and over its motion.
  OutlineSet outline(const StateView& s, double tolerance) const {
    return outline_set(field_, s, tolerance);
  }
  /// The obstacles.
  const ObstacleField& field() const { return field_; }

 protected:
  /// Builds the field from ctx.scene ("obstacles", "inputs"; errors name ctx.context and the
  /// JSON path). The initial particles widen the acceleration grid of `grid_cells` target
  /// cells (0: none); a particle starting beyond kMaxMagnitude is refused with an error
  /// naming `owner` (e.g. "sdf backend").
  explicit FieldBackend(const CreateContext& ctx, long grid_cells = kDefaultGridCells,
                        std::string_view owner = "scene field") {
    std::vector<Vec2> pts;
    for (std::size_t i = 0; i < ctx.initial.n; ++i) {
      pts.push_back(ctx.initial.x.col(static_cast<Eigen::Index>(i)));
      if (!(pts.back().cwiseAbs().maxCoeff() <= kMaxMagnitude))
        throw Error(ctx.context + ": particle " + std::to_string(i) + " starts at (" +
                    num(pts.back().x()) + ", " + num(pts.back().y()) + "), beyond the " +
                    std::string(owner) +
                    "'s coordinate limit of 1e+09 in magnitude (backends/sdf/README.md, "
                    "Limits)");
    }
    field_ = ObstacleField(ctx.scene, ctx.context, pts, grid_cells);
  }

  ObstacleField field_;
};

}  // namespace pinsim::sdf
