#include "rest_cache.hpp"

namespace pinsim::sdf {

void RestCache::begin_step(bool still, const std::vector<uint32_t>& moving,
                           const std::vector<std::size_t>& segments) {
  if (still_segments_.size() != segments.size()) still_segments_.assign(segments.size(), 0);
  bool same_segments = still_;
  for (uint32_t k : moving) {
    same_segments = same_segments && still_segments_[k] == segments[k];
    still_segments_[k] = segments[k];
  }
  if (!(still && same_segments)) ++still_epoch_;
  still_ = still;
}

// A replayed step must compute exactly what the march would. The march's result depends on
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
// replayed only in a step of the same still epoch (the same segments, nothing moving).
bool RestCache::far_from_moving(const RestRecord& m, const ObstacleField& field,
                                const std::vector<double>& speed_bound, double depth_min) const {
  for (uint32_t k : field.moving()) {
    const double lb = field.lower_bound(k, m.x_in) - m.reach - depth_min;
    if (!(lb > 0.0 && lb >= m.d_max)) return false;
    const double uk = speed_bound[k];
    if (uk > 0.0 && !(lb - m.r - depth_min > (m.speed + uk) * m.dt)) return false;
  }
  return true;
}

void RestCache::store(std::size_t i, const RestRecord* hit, const RestRecord& m) {
  const std::size_t j =
      hit != nullptr ? static_cast<std::size_t>(hit - &records_[i * kSlots]) : next_[i];
  if (hit == nullptr) next_[i] = static_cast<uint8_t>((j + 1) % kSlots);
  records_[i * kSlots + j] = m;
  valid_[i] = static_cast<uint8_t>(valid_[i] | 1u << j);
}

}  // namespace pinsim::sdf
