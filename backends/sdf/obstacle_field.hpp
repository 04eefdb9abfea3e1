// ObstacleField: the scene's obstacles (shapes, materials, scripted motion) and the
// queries the backend needs: nearest signed distance at (p, t), normal, obstacle velocity.
#pragma once

#include <cstdint>
#include <optional>
#include <pinsim/plugin.hpp>
#include <string>
#include <vector>

#include "shape.hpp"
#include "timeline.hpp"

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
};

/// Result of a nearest-obstacle query.
struct Nearest {
  double d = HUGE_VAL;  ///< signed distance to the nearest obstacle
  int32_t k = -1;       ///< its index, -1 if there are none
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

  /// Smallest signed distance over all obstacles at point p and time t, and which one.
  Nearest nearest(const Vec2& p, double t) const;
  /// Signed distance and world gradient of obstacle k at (p, t).
  Sdf eval(std::size_t k, const Vec2& p, double t) const;
  /// Velocity of obstacle k's material point at p, time t.
  Vec2 velocity(std::size_t k, const Vec2& p, double t) const;
  /// Bound on how fast obstacle k's distance field can change at a fixed point over
  /// [t0, t1]: the largest speed of any of its points (the Hausdorff distance between two
  /// poses bounds the change of the SDF).
  double speed_bound(std::size_t k, double t0, double t1) const;
  /// Where a point riding rigidly with obstacle k from time t0 ends at time t1.
  Vec2 carry(std::size_t k, const Vec2& p, double t0, double t1) const;
  /// Lower bound of obstacle k's signed distance at p, valid at every time.
  double lower_bound(std::size_t k, const Vec2& p) const;
  /// Grid statistics: cells and mean candidates per cell.
  std::pair<std::size_t, double> grid_stats() const;

 private:
  template <bool G>
  Sdf eval_at(const Obstacle& o, const Vec2& p, double t) const;
  void build_grid(const std::vector<Vec2>& extra, long grid_cells);

  std::vector<Obstacle> obs_;
  std::vector<uint32_t> static_;  ///< indices of static obstacles
  std::vector<uint32_t> moving_;  ///< indices of moving obstacles
  // Uniform grid over static obstacles: cell c lists the obstacles that can be nearest
  // somewhere in the cell (Lipschitz bound: |sdf(p) - sdf(centre)| <= half diagonal).
  Vec2 g_lo_{0.0, 0.0};
  double g_inv_ = 0.0;
  int g_nx_ = 0, g_ny_ = 0;
  std::vector<uint32_t> g_start_;  ///< nx*ny + 1 offsets into g_list_
  std::vector<uint32_t> g_list_;
  std::vector<double> g_lb_;        ///< per entry of g_list_: lower bound of its SDF over the cell
  std::vector<uint32_t> g_mstart_;  ///< the same for moving obstacles that can be nearest
  std::vector<uint32_t> g_mlist_;
};

}  // namespace pinsim::sdf
