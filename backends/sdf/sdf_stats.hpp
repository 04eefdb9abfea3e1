// SdfStats: the sdf backend's counters, shared by the backend and its rest cache.
#pragma once

#include <cstdint>

namespace pinsim::sdf {

/// Counters since construction (for tests, benchmarks and the README's figures).
struct SdfStats {
  uint64_t particle_steps = 0;  ///< particles advanced
  uint64_t skipped = 0;         ///< advanced by one query: clearance exceeded the travel
  uint64_t queries = 0;         ///< nearest-obstacle queries
  uint64_t contacts = 0;        ///< obstacle impulses (including resting contacts)
  uint64_t pair_contacts = 0;   ///< particle-particle impulses
  uint64_t cap_hits = 0;        ///< steps that hit max_collisions or max_iterations
  uint64_t reuses = 0;          ///< particle steps at rest reused from a recorded result (README)
};

/// Counter by counter a - b (what a stretch of work added).
inline SdfStats operator-(const SdfStats& a, const SdfStats& b) {
  return {a.particle_steps - b.particle_steps,
          a.skipped - b.skipped,
          a.queries - b.queries,
          a.contacts - b.contacts,
          a.pair_contacts - b.pair_contacts,
          a.cap_hits - b.cap_hits,
          a.reuses - b.reuses};
}

/// Counter by counter a += b.
inline void add(SdfStats& a, const SdfStats& b) {
  a.particle_steps += b.particle_steps;
  a.skipped += b.skipped;
  a.queries += b.queries;
  a.contacts += b.contacts;
  a.pair_contacts += b.pair_contacts;
  a.cap_hits += b.cap_hits;
  a.reuses += b.reuses;
}

}  // namespace pinsim::sdf
