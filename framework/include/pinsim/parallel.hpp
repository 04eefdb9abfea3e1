// pinsim/parallel.hpp: fixed-chunk parallel loops for plugins, bit-identical for any thread
// count (header-only).
//
// The host limits oneTBB to `--threads` threads while a simulation lives (a
// tbb::global_control). A plugin loop written with for_chunks() runs its chunks on those
// threads; in a build without oneTBB
// (PINSIM_WITH_TBB undefined: the web build, out-of-tree plugins) it runs them one after
// another. Chunks are fixed by the item count and the chunk size alone, never by the thread
// count, so a body that writes only what belongs to its own items (and reads nothing another
// chunk writes) gives the same bits with 1, 2 or 64 threads. Anything summed over items is
// summed per chunk into a slot of its own and then over the slots in chunk order.
#pragma once

#include <algorithm>
#include <cstddef>

#ifdef PINSIM_WITH_TBB
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>
#endif

namespace pinsim {

/// Threads the current call may use: the host's --threads (oneTBB's global limit, or the
/// current task_arena's concurrency if smaller), 1 in a build without oneTBB.
inline int available_threads() {
#ifdef PINSIM_WITH_TBB
  const auto limit =
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  return static_cast<int>(std::min<std::size_t>(
      limit, static_cast<std::size_t>(tbb::this_task_arena::max_concurrency())));
#else
  return 1;
#endif
}

/// Items per chunk for loops that do a few arithmetic operations per particle (the
/// integrators' updates, the step checks, uniform gravity): below two chunks such a loop runs
/// serially. A parallel loop costs about 10 us more than its work (waking oneTBB's threads);
/// 32768 particles take 15-50 us in these loops, so smaller states gain nothing from threads
/// (10,000 balls: 57 us of such loops per step serially, 130 us with 8192-particle chunks).
inline constexpr std::size_t kParticleChunk = 32768;

/// Number of chunks of `chunk` items in [0, n).
inline std::size_t chunk_count(std::size_t n, std::size_t chunk) {
  return chunk == 0 ? 0 : (n + chunk - 1) / chunk;
}

/// Calls body(c, begin, end) once for each chunk c of [0, n): [c chunk, min(n, (c+1) chunk)),
/// in parallel when more than one thread is available and there is more than one chunk, else
/// in order on the calling thread. An exception from a body reaches the caller (with threads,
/// one of them), after the running chunks end.
template <class Body>
void for_chunks(std::size_t n, std::size_t chunk, Body&& body) {
  if (n <= chunk) {  // one chunk (or none): the serial loop, nothing else on the way
    if (n > 0) body(std::size_t{0}, std::size_t{0}, n);
    return;
  }
  const std::size_t chunks = chunk_count(n, chunk);
  auto run = [&](std::size_t c) { body(c, c * chunk, std::min(n, (c + 1) * chunk)); };
#ifdef PINSIM_WITH_TBB
  if (chunks > 1 && available_threads() > 1) {
    // simple_partitioner with grain 1: every chunk is one task, whatever the thread count
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, chunks, 1),
        [&](const tbb::blocked_range<std::size_t>& r) {
          for (std::size_t c = r.begin(); c != r.end(); ++c) run(c);
        },
        tbb::simple_partitioner());
    return;
  }
#endif
  for (std::size_t c = 0; c < chunks; ++c) run(c);
}

}  // namespace pinsim
