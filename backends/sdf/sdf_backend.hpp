// SdfBackend: continuous collision of disc particles against SDF obstacles by sphere
// tracing, with impulses at the time of impact, moving obstacles and optional
// particle-particle contacts.
#pragma once

#include <cstdint>
#include <pinsim/plugin.hpp>
#include <vector>

#include "obstacle_field.hpp"

namespace pinsim::sdf {

/// Counters since construction (for tests, benchmarks and the README's figures).
struct SdfStats {
  uint64_t particle_steps = 0;  ///< particles advanced
  uint64_t skipped = 0;         ///< advanced by one query: clearance exceeded the travel
  uint64_t queries = 0;         ///< nearest-obstacle queries
  uint64_t contacts = 0;        ///< obstacle impulses (including resting contacts)
  uint64_t pair_contacts = 0;   ///< particle-particle impulses
  uint64_t cap_hits = 0;        ///< steps that hit max_collisions or max_iterations
  uint64_t replays = 0;  ///< particle steps at rest repeated from the previous result (README)
};

class SdfBackend {
 public:
  static PluginInfo info();
  explicit SdfBackend(const CreateContext& ctx);

  /// Moves every particle with finite mass along its velocity over [s.t, s.t + dt],
  /// resolving each contact at its time of impact.
  void advance(MutableState& s, double dt, EventSink& ev);
  /// Signed distance from p to the nearest obstacle at time t (HUGE_VAL if none).
  double distance(const Vec2& p, double t, int64_t* obstacle) const;

  const SdfStats& stats() const { return stats_; }
  const ObstacleField& field() const { return field_; }
  double depth_min() const { return delta_; }
  double march_tolerance() const { return tol_; }

 private:
  struct Budget {
    int collisions = 0;
    int iterations = 0;
  };
  struct Change {
    double tau;  ///< time into the step, s
    Vec2 dv;     ///< velocity change
  };
  /// What a march looked at, to decide whether its result can be replayed (see README).
  struct Probe {
    Vec2 x0{0.0, 0.0};        ///< start point
    double reach = 0.0;       ///< farthest query point from x0
    double d_max = 0.0;       ///< largest nearest distance returned
    double speed = 0.0;       ///< largest speed at a query
    bool static_only = true;  ///< every query's nearest obstacle static, no moving one near
    bool at_rest = false;     ///< ended at rest after one resting contact, no event
  };
  /// A particle step that ended at rest: the same input gives the same output as long as
  /// no moving obstacle can come near (a record on static obstacles), or as long as every
  /// moving obstacle stands still in the pose it had (a record in a still epoch).
  struct Rest {
    Vec2 x_in, v_in, x_out, v_out;
    double r = 0.0, dt = 0.0;
    double reach = 0.0, d_max = 0.0, speed = 0.0;
    SdfStats delta;         ///< counters the step added
    uint64_t epoch = 0;     ///< still_epoch_ of the step, if it relied on one
    bool in_epoch = false;  ///< a moving obstacle was near: valid only in that epoch
  };
  /// Moves particle i from (x, v) at time t over `dur`; false if the caps stopped it early.
  bool march(std::size_t i, Vec2& x, Vec2& v, double r, double t, double dur, Budget& b,
             EventSink& ev, Probe* probe = nullptr);
  /// Step along a sliding contact with static obstacle k (see sdf_backend.cpp), 0 if none.
  double slide_step(std::size_t k, const Vec2& x, const Vec2& v, double r, double remaining,
                    double lip) const;
  /// True if no moving obstacle can reach the points a Rest record's step queried, in the
  /// step now being taken, so the record can be replayed.
  bool far_from_moving(const Rest& m) const;
  /// Particle-particle contacts within the step: fills changes_ (see README).
  void schedule_pairs(const MutableState& s, double dt, EventSink& ev);

  ObstacleField field_;
  double delta_ = 1e-5;  ///< contact offset ("depthMin"), scene length
  double tol_ = 1e-6;    ///< march tolerance above the offset, scene length
  int max_collisions_ = 16;
  int max_iterations_ = 200;
  double rest_speed_ = 0.0;
  bool particle_contacts_ = false;
  double particle_e_ = 1.0;
  std::vector<double> speed_bound_;         ///< per obstacle, this step
  std::vector<std::size_t> timeline_hint_;  ///< per obstacle: its timeline's segment last step
  /// Still epochs: a run of steps in which no moving obstacle moves, each in one pose (the
  /// same timeline segments, hence the same angle or position and its cos/sin, to the bit).
  /// still_ is true in such a step; still_epoch_ numbers the run and changes whenever a
  /// step moves or the segments change, so equal numbers mean equal poses.
  bool still_ = false;
  uint64_t still_epoch_ = 0;
  std::vector<std::size_t> still_segments_;
  std::vector<std::vector<Change>> changes_;
  /// Rest records per particle: a resting ball's position may cycle through a few values
  /// (rounding of the push back to the contact offset), so a few are kept.
  static constexpr std::size_t kRestSlots = 4;
  std::vector<Rest> rest_;           ///< kRestSlots per particle
  std::vector<uint8_t> rest_valid_;  ///< per particle: bit j set if slot j holds a record
  std::vector<uint8_t> rest_next_;   ///< per particle: the slot to fill next
  SdfStats stats_;
};

}  // namespace pinsim::sdf
