// What the sdf backend reports of a drift while the host records it for the adjoint of a run
// (ABI 4.3 record_drift, pinsim_drift_sink): the state entering the step, the pair hits of
// the schedule, every velocity change of a particle with the normal, its derivatives and the
// obstacle's velocity at the impact, and where the step is not differentiable (README,
// "The differentiable step"; docs/gradients.md).
#pragma once

#include <pinsim/abi.h>

#include <cstdint>
#include <pinsim/plugin.hpp>
#include <pinsim/scene_field.hpp>
#include <utility>
#include <vector>

namespace pinsim::sdf {

class DriftRecorder {
 public:
  /// Report to `sink` from the next advance() on (null: stop).
  void set(const pinsim_drift_sink* sink);
  bool on() const { return on_; }

  /// The state entering advance() over dt; resets the pair numbering.
  void begin(const MutableState& s, double dt);
  /// A pair hit of the schedule, with the two discs' tracks before it (the schedule's
  /// x(tau) = xr + vc (tau - tr)), before the tracks change. Numbers the velocity changes
  /// it gives particle i (if w_i > 0) and j (if w_j > 0) in the order the schedule pushes them.
  void pair(uint32_t i, uint32_t j, double tau, const Vec2& xr_i, const Vec2& vc_i, double tr_i,
            const Vec2& xr_j, const Vec2& vc_j, double tr_j, double radius_sum, double w_i,
            double w_j, double restitution);
  /// The c-th scheduled velocity change of particle i, at tau into the step, at x.
  void change(std::size_t i, std::size_t c, double tau, const Vec2& x, const Vec2& v_before,
              const Vec2& v_after);
  /// An impulse of obstacle k on particle i at absolute time t, centre x (before a push back
  /// to the offset): a time of impact if `toi`, else an impulse inside the band. The normal's
  /// derivatives and the obstacle's velocity come from the field by central differences of
  /// its gradient and velocity (the field has no analytic Hessian).
  void impact(const ObstacleField& field, std::size_t i, std::size_t k, bool toi, double t,
              const Vec2& x, const Vec2& v_before, const Vec2& v_after, double offset, bool resting,
              bool emitted);
  /// A place where the step is not differentiable, or close to it (PINSIM_FINDING_*).
  void finding(uint32_t kind, std::size_t i, int64_t obstacle, double t, double margin);

 private:
  pinsim_drift_sink sink_{};
  bool on_ = false;
  double t0_ = 0.0, dt_ = 0.0;
  int64_t pairs_ = 0;
  std::vector<std::vector<std::pair<int64_t, int64_t>>> change_ids_;  ///< per particle
};

}  // namespace pinsim::sdf
