#include "core/contact_tracker.hpp"

namespace pinsim {

uint64_t ContactTracker::key_of(const pinsim_event& e) {
  // Particle in the high 32 bits; the partner in the low 32: an obstacle index, or another
  // particle with the top bit set. (Scenes stay far below 2^31 particles and obstacles.)
  const uint64_t partner = e.obstacle >= 0
                               ? static_cast<uint64_t>(e.obstacle) & 0x7fffffffu
                               : (static_cast<uint64_t>(e.other) & 0x7fffffffu) | 0x80000000u;
  return (static_cast<uint64_t>(e.particle) << 32) | partner;
}

void ContactTracker::move_open(std::size_t from, std::size_t to) {
  auto [b, e] = index_.equal_range(open_[from].key);
  for (auto it = b; it != e; ++it)
    if (it->second == from) {
      it->second = to;
      break;
    }
  open_[to] = open_[from];
}

void ContactTracker::step(uint64_t step, const std::vector<pinsim_event>& events,
                          std::vector<pinsim_event>& impacts, std::vector<ContactSpan>& closed) {
  for (const pinsim_event& e : events) {
    const std::size_t p = static_cast<std::size_t>(e.particle);
    const double inv_m = p < inv_mass_.size() ? inv_mass_[p] : 0.0;
    const double j = inv_m > 0.0 ? (e.vn_after - e.vn_before) / inv_m : 0.0;
    const uint64_t key = key_of(e);
    // The pair's open touch with the nearest normal continues, if it is near enough.
    std::size_t at = open_.size();
    double best = kMaxTurnCos;
    auto [b, end] = index_.equal_range(key);
    for (auto it = b; it != end; ++it) {
      const Open& o = open_[it->second];
      const double c = o.normal[0] * e.normal[0] + o.normal[1] * e.normal[1];
      if (c >= best) {
        best = c;
        at = it->second;
      }
    }
    if (at == open_.size()) {
      Open o;
      o.key = key;
      o.span.particle = e.particle;
      o.span.obstacle = e.obstacle;
      o.span.other = e.other;
      o.span.t_begin = e.t;
      open_.push_back(o);
      index_.emplace(key, at);
      impacts.push_back(e);
    }
    Open& o = open_[at];
    o.last_step = step;
    o.normal[0] = e.normal[0];
    o.normal[1] = e.normal[1];
    o.span.t_end = e.t;
    ++o.span.impulses;
    o.span.impulse += j;
  }
  // Touches without an impulse for kGapSteps steps have ended. Swap-remove keeps this
  // O(open).
  for (std::size_t i = 0; i < open_.size();) {
    if (step - open_[i].last_step < kGapSteps) {
      ++i;
      continue;
    }
    closed.push_back(open_[i].span);
    auto [b, e] = index_.equal_range(open_[i].key);
    for (auto it = b; it != e; ++it)
      if (it->second == i) {
        index_.erase(it);
        break;
      }
    if (i + 1 != open_.size()) move_open(open_.size() - 1, i);
    open_.pop_back();
  }
}

void ContactTracker::close_all(std::vector<ContactSpan>& closed) {
  for (Open& o : open_) {
    o.span.open = true;
    closed.push_back(o.span);
  }
  open_.clear();
  index_.clear();
}

}  // namespace pinsim
