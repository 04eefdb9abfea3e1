// ObstacleField: the scene's obstacles (shapes, materials, scripted motion) and the
// queries the backend needs: nearest signed distance at (p, t), normal, obstacle velocity.
#pragma once

#include <cstdint>
#include <optional>
#include <pinsim/plugin.hpp>
#include <pinsim/scene_field/shape.hpp>
#include <pinsim/scene_field/timeline.hpp>
#include <string>
#include <vector>

namespace pinsim::sdf {

/// Contact material of an obstacle.
struct Material {
  double restitution = 1.0;  ///< e in [0, 1]
  double friction = 0.0;     ///< Coulomb coefficient mu >= 0
  double kick = 0.0;         ///< speed added along the normal on every impact, units/s
};

enum class MotionType : uint8_t { kStatic, kFlipper, kSlider };

struct Obstacle {
  std::string id;
  ShapeTree shape;  ///< in the obstacle's own frame (world frame for static obstacles)
  Material material;
  MotionType motion = MotionType::kStatic;
  Vec2 pivot{0.0, 0.0};              ///< flipper pivot
  Vec2 offset{0.0, 0.0};             ///< slider displacement at lambda = 1
  double reach = 0.0;                ///< flipper: max distance of the shape from the pivot
  Aabb sweep;                        ///< slider: bounds over the whole stroke
  std::optional<Timeline> timeline;  ///< flipper angle or slider lambda
  std::string input;                 ///< the input its motion listens to (moving only)
};

/// Result of a nearest-obstacle query.
struct Nearest {
  double d = HUGE_VAL;  ///< signed distance to the nearest obstacle
  int32_t k = -1;       ///< its index, -1 if there are none
  Vec2 g{0.0, 1.0};     ///< its gradient there (only from nearest_with_gradient)
};

class ObstacleField {
 public:
  ObstacleField() = default;
  /// Parses scene["obstacles"] and scene["inputs"]; `ctx` is the file name for errors.
  /// `extra` points (the initial particles) widen the acceleration grid. `grid_cells` is
  /// the target number of grid cells (0: no grid).
  ObstacleField(const nlohmann::json& scene, const std::string& ctx, const std::vector<Vec2>& extra,
                long grid_cells);

  std::size_t size() const { return obs_.size(); }
  const Obstacle& obstacle(std::size_t k) const { return obs_[k]; }
  const std::vector<uint32_t>& moving() const { return moving_; }

  /// Input `name` pressed or released at time t (at or after its previous event): appends
  /// the event to the timeline of every obstacle listening to it, as if the scene's
  /// "inputs" had listed it. Throws Error naming an input no obstacle listens to, or an
  /// event earlier than the input's last one.
  void input(const std::string& name, bool pressed, double t);

  /// Smallest signed distance over all obstacles at point p and time t, and which one.
  Nearest nearest(const Vec2& p, double t) const;
  /// The same, with the nearest obstacle's gradient (as eval(k, p, t).g) in Nearest::g.
  Nearest nearest_with_gradient(const Vec2& p, double t) const;
  /// Signed distance and world gradient of obstacle k at (p, t).
  Sdf eval(std::size_t k, const Vec2& p, double t) const;
  /// Velocity of obstacle k's material point at p, time t.
  Vec2 velocity(std::size_t k, const Vec2& p, double t) const;
  /// Bound on how fast obstacle k's distance field can change at a fixed point over
  /// [t0, t1]: the largest speed of any of its points (the Hausdorff distance between two
  /// poses bounds the change of the SDF). `hint` speeds up the timeline search for times
  /// that advance step by step (0 at first; updated).
  double speed_bound(std::size_t k, double t0, double t1, std::size_t& hint) const;
  /// Where a point riding rigidly with obstacle k from time t0 ends at time t1.
  Vec2 carry(std::size_t k, const Vec2& p, double t0, double t1) const;
  /// Lower bound of obstacle k's signed distance at p, valid at every time.
  double lower_bound(std::size_t k, const Vec2& p) const;
  /// Lower bound of static obstacle k's signed distance over the segment from a to b.
  double segment_lower_bound(std::size_t k, const Vec2& a, const Vec2& b) const {
    return obs_[k].shape.segment_bounds(a, b).first;
  }
  /// Lower bound, valid at every time, of the signed distance at p to every obstacle but k:
  /// static obstacles evaluated, moving ones by lower_bound.
  double clearance_except(std::size_t k, const Vec2& p) const;
  /// Grid statistics: cells and mean candidates per cell.
  std::pair<std::size_t, double> grid_stats() const;

  /// Obstacle k's boundary at time t, world frame, and its bounds then and over every pose
  /// its motion can take (see obstacle_outline.cpp).
  struct Outline {
    std::vector<Ring> rings;  ///< closed, the solid on the left
    Aabb bounds;              ///< of the rings at t
    Aabb sweep;               ///< of the rings over the motion's whole range
  };
  /// The outline of obstacle k at time t within `tol`; half-planes cut to `clip`.
  Outline outline(std::size_t k, double t, double tol, const Ring& clip) const;
  /// Bounds of the obstacles' bounded parts over all time: static boundaries, each
  /// flipper's reach about its pivot, each slider's stroke.
  Aabb finite_bounds() const;
  /// The default outline tolerance: 1e-3 of the larger side of finite_bounds() (1e-3 if
  /// that is empty).
  double default_outline_tolerance() const;
  /// The rectangle unbounded obstacles (half-planes) are cut to: finite_bounds(), the
  /// half-planes' points and the `extra` points, grown on every side by a tenth of its
  /// larger side (1 if that is 0).
  Ring outline_clip(const std::vector<Vec2>& extra) const;

 private:
  template <bool G>
  Sdf eval_at(const Obstacle& o, const Vec2& p, double t) const;
  void build_grid(const std::vector<Vec2>& extra, long grid_cells);
  /// Lower bound of obstacle k's SDF within `rad` of c, at every time (for grid cells).
  double cell_lower_bound(std::size_t k, const Vec2& c, double rad) const;
  template <bool G>
  Nearest nearest_impl(const Vec2& p, double t) const;

  std::vector<Obstacle> obs_;
  std::vector<uint32_t> static_;  ///< indices of static obstacles
  std::vector<uint32_t> moving_;  ///< indices of moving obstacles
  // Uniform grid over static obstacles: cell c lists the obstacles that can be nearest
  // somewhere in the cell (Lipschitz bound: |sdf(p) - sdf(centre)| <= half diagonal).
  // A query touches one 12-byte cell, which holds the static candidate of least lower
  // bound (evaluated first, always), and the cell's other candidates, stored contiguously:
  // first the static ones in increasing order of their lower bound over the cell, then the
  // moving ones that can be nearest there.
  struct Cell {
    uint32_t first = 0;    ///< index of the cell's second candidate in g_cand_
    uint16_t statics = 0;  ///< static candidates after the first
    uint16_t moving = 0;   ///< moving candidates after them
    uint16_t k0 = 0;       ///< first static candidate: obstacle index
    uint16_t node0 = 0;    ///< and its reduced tree, as Candidate::node
  };
  struct Candidate {
    float lb = 0.0f;    ///< lower bound of the obstacle's SDF over the cell, rounded down
    uint16_t k = 0;     ///< obstacle index
    uint16_t node = 0;  ///< static: its tree reduced over the cell, node | neg << 15
  };
  Vec2 g_lo_{0.0, 0.0};
  double g_inv_ = 0.0;
  int g_nx_ = 0, g_ny_ = 0;
  std::vector<Cell> g_cells_;  ///< nx*ny, row by row
  std::vector<Candidate> g_cand_;
};

/// Every obstacle's outline for the state s (time s.t; its particles widen the clip of
/// half-planes) within `tolerance` (<= 0: field.default_outline_tolerance()), as a backend's
/// outline() returns it.
OutlineSet outline_set(const ObstacleField& field, const StateView& s, double tolerance);

}  // namespace pinsim::sdf
