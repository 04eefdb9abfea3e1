// RestCache: the sdf backend's particle steps that ended at rest, replayed when the same
// input comes again and nothing that moves can have changed the result (see README).
#pragma once

#include <cstddef>
#include <cstdint>
#include <pinsim/plugin.hpp>
#include <vector>

#include "obstacle_field.hpp"
#include "sdf_stats.hpp"

namespace pinsim::sdf {

/// What a march looked at, to decide whether its result can be replayed (see README).
struct RestProbe {
  Vec2 x0{0.0, 0.0};        ///< start point
  double reach = 0.0;       ///< farthest query point from x0, squared
  double d_max = 0.0;       ///< largest nearest distance returned
  double speed = 0.0;       ///< largest speed at a query
  bool static_only = true;  ///< every query's nearest obstacle static, no moving one near
  bool at_rest = false;     ///< ended at rest after one resting contact, no event
};

/// A particle step that ended at rest: the same input gives the same output as long as
/// no moving obstacle can come near (a record on static obstacles), or as long as every
/// moving obstacle stands still in the pose it had (a record in a still epoch).
struct RestRecord {
  Vec2 x_in, v_in, x_out, v_out;
  double r = 0.0, dt = 0.0;
  double reach = 0.0, d_max = 0.0, speed = 0.0;
  SdfStats delta;         ///< counters the step added
  uint64_t epoch = 0;     ///< the still epoch of the step, if it relied on one
  bool in_epoch = false;  ///< a moving obstacle was near: valid only in that epoch
};

class RestCache {
 public:
  /// Starts a step: `still` if no moving obstacle moves in it; `segments` holds each
  /// obstacle's timeline segment for the step (read for the `moving` ones).
  void begin_step(bool still, const std::vector<uint32_t>& moving,
                  const std::vector<std::size_t>& segments);
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
  bool replayable(const RestRecord& m, const ObstacleField& field,
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
  bool far_from_moving(const RestRecord& m, const ObstacleField& field,
                       const std::vector<double>& speed_bound, double depth_min) const;

  /// Still epochs: a run of steps in which no moving obstacle moves, each in one pose (the
  /// same timeline segments, hence the same angle or position and its cos/sin, to the bit).
  /// still_ is true in such a step; still_epoch_ numbers the run and changes whenever a
  /// step moves or the segments change, so equal numbers mean equal poses.
  bool still_ = false;
  uint64_t still_epoch_ = 0;
  std::vector<std::size_t> still_segments_;  ///< per obstacle: its segment last step
  /// Records per particle: a resting ball's position may cycle through a few values
  /// (rounding of the push back to the contact offset), so a few are kept.
  static constexpr std::size_t kSlots = 4;
  std::vector<RestRecord> records_;  ///< kSlots per particle
  std::vector<uint8_t> valid_;       ///< per particle: bit j set if slot j holds a record
  std::vector<uint8_t> next_;        ///< per particle: the slot to fill next
};

}  // namespace pinsim::sdf
