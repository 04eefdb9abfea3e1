// Contacts from a backend's per-step impulses: which impulse begins a touch (an impact) and
// how long each touch lasts, like Box2D v3's begin/end touch and hit events. Host side, so the
// same for every backend.
#pragma once

#include <pinsim/abi.h>

#include <cstdint>
#include <unordered_map>
#include <vector>

namespace pinsim {

/// One touch of a particle with an obstacle or another particle: impulses on that pair in
/// consecutive steps.
struct ContactSpan {
  int64_t particle = -1;
  int64_t obstacle = -1;  ///< obstacle index, or -1
  int64_t other = -1;     ///< other particle, or -1
  double t_begin = 0.0;   ///< time of the first impulse, s
  double t_end = 0.0;     ///< time of the last impulse, s
  uint64_t impulses = 0;  ///< impulses in the touch
  double impulse = 0.0;   ///< sum of m (vn_after - vn_before) over them, N s (mass of `particle`)
  bool open = false;      ///< still touching when the run ended
};

/// Tracks touches step by step. An impact is an approach: an impulse on a pair (particle,
/// obstacle or other particle) begins a touch, and is that touch's impact, unless it
/// continues one of the pair's open touches: one whose last impulse was at most kGapSteps
/// steps before, with a normal within kMaxTurnCos (cos 30 degrees) of this impulse's. A
/// touch ends when kGapSteps steps pass without an impulse continuing it.
/// The gap: a ball sliding along a curved wall with restitution bounces off by a fraction
/// of the backend's rest speed and is back one to a few steps later.
/// The normal: one obstacle may have several faces (a box, a polygon). A ball that hits
/// one face and, a few steps later, another face of the same obstacle approaches a new
/// surface: two impacts, two touches. Along a smooth wall the normal turns by the distance
/// slid over the radius of curvature, a few degrees per step; at a concave corner between
/// faces it jumps by the corner's turn (90 degrees in a box). A ball resting in a corner
/// keeps two touches open, one per face.
/// Memory: one entry per touch open at the time, nothing kept for closed ones.
class ContactTracker {
 public:
  static constexpr uint64_t kGapSteps = 4;
  /// cos 30 degrees: impulses on a pair whose normals differ by more are on different
  /// surfaces.
  static constexpr double kMaxTurnCos = 0.8660254037844386;

  /// `inv_mass`: 1/mass per particle (0: pinned; its impulses count 0).
  explicit ContactTracker(std::vector<double> inv_mass) : inv_mass_(std::move(inv_mass)) {}

  /// Feeds the impulses of step `step` (steps counted up by one each call, or more).
  /// Appends the impulses that begin a touch to `impacts` and the touches that ended
  /// (none for kGapSteps steps) to `closed`.
  void step(uint64_t step, const std::vector<pinsim_event>& events,
            std::vector<pinsim_event>& impacts, std::vector<ContactSpan>& closed);
  /// Appends every open touch to `closed`, marked open, and forgets them.
  void close_all(std::vector<ContactSpan>& closed);
  std::size_t open() const { return open_.size(); }

 private:
  struct Open {
    ContactSpan span;
    uint64_t last_step = 0;
    uint64_t key = 0;
    double normal[2] = {0.0, 0.0};  ///< the last impulse's
  };
  /// Moves the touch at open_[from] to open_[to] and updates its index entry.
  void move_open(std::size_t from, std::size_t to);
  static uint64_t key_of(const pinsim_event& e);

  std::vector<double> inv_mass_;
  std::vector<Open> open_;
  std::unordered_multimap<uint64_t, std::size_t> index_;  ///< key -> positions in open_
};

}  // namespace pinsim
