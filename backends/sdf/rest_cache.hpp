// RestCache: the sdf backend's particle steps that ended at rest, reused when the same
// input comes again and nothing that moves can have changed the result (see README).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <pinsim/plugin.hpp>
#include <pinsim/scene_field/obstacle_field.hpp>
#include <vector>

#include "sdf_stats.hpp"

namespace pinsim::sdf {

/// What a march looked at, to decide whether its result can be reused (see README).
struct RestProbe {
  Vec2 x0{0.0, 0.0};        ///< start point
  double reach = 0.0;       ///< farthest query point from x0, squared
  double d_max = 0.0;       ///< largest nearest distance returned
  double speed = 0.0;       ///< largest speed at a query
  bool static_only = true;  ///< every query's nearest obstacle static, no moving one near
  bool at_rest = false;     ///< ended at rest after one resting contact, no event

  /// Takes in one query of the march: at x the nearest distance d, the particle's speed, and
  /// whether a moving obstacle was near or the nearest one moves.
  void observe(const Vec2& x, double d, double v, bool moving) {
    reach = std::max(reach, (x - x0).squaredNorm());
    d_max = std::max(d_max, d);
    speed = std::max(speed, v);
    if (moving) static_only = false;
  }
};

/// A particle step that ended at rest: the same input gives the same output as long as
/// no moving obstacle can come near (a record on static obstacles), or as long as every
/// moving obstacle stands still in the pose it had (a record in a still epoch).
struct RestRecord {
  Vec2 x_in, v_in, x_out, v_out;
  double r = 0.0, dt = 0.0;
  double reach = 0.0, d_max = 0.0, speed = 0.0;
  SdfStats added;         ///< counters the step added
  uint64_t epoch = 0;     ///< the still epoch of the step, if it relied on one
  bool in_epoch = false;  ///< a moving obstacle was near: valid only in that epoch
};

class RestCache {
 public:
  /// Starts a step: `still` if no moving obstacle moves in it, `same_segments` if every
  /// moving obstacle's timeline is in the segment it was in the step before. A new still
  /// epoch begins unless this step and the one before are still in the same segments.
  void begin_step(bool still, bool same_segments) {
    if (!(still && still_ && same_segments)) ++still_epoch_;
    still_ = still;
  }
  /// True if no moving obstacle moves in this step.
  bool still() const { return still_; }
  /// The current still epoch (equal numbers mean equal poses of the moving obstacles).
  uint64_t epoch() const { return still_epoch_; }

  /// Room for n particles; every record is forgotten when n changes.
  void resize(std::size_t n) {
    if (valid_.size() == n) return;
    valid_.assign(n, 0);
    next_.assign(n, 0);
    records_.resize(n * kSlots);
  }
  /// Particle i's record for exactly this input, or nullptr.
  const RestRecord* find(std::size_t i, const Vec2& x, const Vec2& v, double r, double dt) const {
    for (std::size_t j = 0; j < kSlots && valid_[i] >> j; ++j) {
      const RestRecord& m = records_[i * kSlots + j];
      if ((valid_[i] >> j & 1) && same(x, m.x_in) && same(v, m.v_in) && r == m.r && dt == m.dt)
        return &m;
    }
    return nullptr;
  }
  /// True if record m (found for this step's input) gives this step's result.
  bool reusable(const RestRecord& m, const ObstacleField& field,
                const std::vector<double>& speed_bound, double depth_min) const {
    return m.in_epoch ? still_ && m.epoch == still_epoch_
                      : far_from_moving(m, field, speed_bound, depth_min);
  }
  /// Keeps m as particle i's record: in the slot of `hit` (a record found for the same
  /// input), else in the next slot in turn.
  void store(std::size_t i, const RestRecord* hit, const RestRecord& m);
  /// Forgets particle i's records.
  void forget(std::size_t i) { valid_[i] = 0; }

 private:
  static bool same(const Vec2& a, const Vec2& b) { return a.x() == b.x() && a.y() == b.y(); }

  // True if no moving obstacle can reach the points m's step queried, in this step.
  // A reused step must compute exactly what the march would. The march's result depends on
  // time only through moving obstacles: their distance in nearest() and their speed in the
  // Lipschitz bound. For every moving obstacle k, lower_bound(k, .) is 1-Lipschitz and time
  // independent, so at every point the recorded step queried (within `reach` of x_in)
  //   lower_bound(k, x_in) - reach - depth_min >= d_max   => nearest() skips k there, and
  //   ... - r - depth_min > (speed + U_k) dt                => k adds nothing to the bound
  // (depth_min is a margin against rounding, far above it).
  // A ball resting on a moving obstacle that stands still (a raised flipper, a stopped
  // plunger) cannot pass that test. Instead: in a step where no moving obstacle moves
  // (every speed bound over the step 0), each obstacle's distance, gradient and velocity (0)
  // come from its standing timeline segment and do not depend on the time, so the march is
  // a pure function of its input and of those segments. A record made in such a step is
  // reused only in a step of the same still epoch (the same segments, nothing moving).
  static bool far_from_moving(const RestRecord& m, const ObstacleField& field,
                              const std::vector<double>& speed_bound, double depth_min) {
    for (uint32_t k : field.moving()) {
      const double lb = field.lower_bound(k, m.x_in) - m.reach - depth_min;
      if (!(lb > 0.0 && lb >= m.d_max)) return false;
      const double uk = speed_bound[k];
      if (uk > 0.0 && !(lb - m.r - depth_min > (m.speed + uk) * m.dt)) return false;
    }
    return true;
  }

  /// Still epochs: a run of steps in which no moving obstacle moves, each in one pose (the
  /// same timeline segments, hence the same angle or position and its cos/sin, to the bit).
  /// still_ is true in such a step; still_epoch_ numbers the run and changes whenever a
  /// step moves or the segments change, so equal numbers mean equal poses.
  bool still_ = false;
  uint64_t still_epoch_ = 0;
  /// Records per particle: a resting ball's position may cycle through a few values
  /// (rounding of the push back to the contact offset), so a few are kept.
  static constexpr std::size_t kSlots = 4;
  std::vector<RestRecord> records_;  ///< kSlots per particle
  std::vector<uint8_t> valid_;       ///< per particle: bit j set if slot j holds a record
  std::vector<uint8_t> next_;        ///< per particle: the slot to fill next
};

}  // namespace pinsim::sdf
