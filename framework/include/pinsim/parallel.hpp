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
#include <tbb/task_group.h>
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

/// Items per chunk of the per-particle loops (the integrators' updates, the step checks and
/// their sums, uniform gravity). With Schedule::Even each thread takes one run of
/// consecutive chunks, so a small chunk costs no extra tasks; it fixes only how sums are
/// grouped (one partial sum per chunk, added in chunk order).
inline constexpr std::size_t kParticleChunk = 1024;

/// Items from which Schedule::Even loops run on threads: below it (one ball, a small blob)
/// the serial loop, with nothing else on the way, since waking a second thread costs about
/// as much as these loops' work on fewer items.
inline constexpr std::size_t kParallelItems = 4096;

/// How for_chunks hands its chunks to threads; either gives the same bits.
enum class Schedule {
  /// every chunk one task, taken by whichever thread is free: for chunks whose cost varies
  /// (a particle's march, a spring chunk)
  Dynamic,
  /// each thread one run of consecutive chunks (tbb::static_partitioner), serial below
  /// kParallelItems items: for cheap loops whose chunks all cost the same
  Even,
};

/// Number of chunks of `chunk` items in [0, n).
inline std::size_t chunk_count(std::size_t n, std::size_t chunk) {
  return chunk == 0 ? 0 : (n + chunk - 1) / chunk;
}

/// Calls body(c, begin, end) once for each chunk c of [0, n): [c chunk, min(n, (c+1) chunk)),
/// in parallel when more than one thread is available and there is more than one chunk (and,
/// for Schedule::Even, at least kParallelItems items), else in order on the calling thread.
/// An exception from a body reaches the caller (with threads, one of them), after the running
/// chunks end.
template <class Body>
void for_chunks(std::size_t n, std::size_t chunk, Body&& body,
                Schedule schedule = Schedule::Dynamic) {
  if (n <= chunk) {  // one chunk (or none): the serial loop, nothing else on the way
    if (n > 0) body(std::size_t{0}, std::size_t{0}, n);
    return;
  }
  const std::size_t chunks = chunk_count(n, chunk);
  auto run = [&](std::size_t c) { body(c, c * chunk, std::min(n, (c + 1) * chunk)); };
#ifdef PINSIM_WITH_TBB
  const bool even = schedule == Schedule::Even;
  if ((!even || n >= kParallelItems) && available_threads() > 1) {
    auto range = [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t c = r.begin(); c != r.end(); ++c) run(c);
    };
    const tbb::blocked_range<std::size_t> all(0, chunks, 1);
    if (even)  // one run of chunks per thread: the fewest tasks
      tbb::parallel_for(all, range, tbb::static_partitioner());
    else  // grain 1: every chunk is one task, whatever the thread count
      tbb::parallel_for(all, range, tbb::simple_partitioner());
    return;
  }
#else
  (void)schedule;
#endif
  for (std::size_t c = 0; c < chunks; ++c) run(c);
}

/// Runs first() on the calling thread and second() beside it when more than one thread is
/// available (loops inside them share the threads), else first() then second(). For two
/// pieces of work that share nothing they write, or whose sharing the caller orders itself
/// (atomics, with waits that never depend on the other piece having started). So first() may
/// call what must be called from the caller's thread (an event sink). With threads an
/// exception from either reaches the caller after both end (first()'s if both throw; a throw
/// from first() cancels what of second() has not started); without, second() does not run
/// after first() throws. second() runs in a context of its own: the cancellation of an
/// enclosing parallel loop never skips it silently.
template <class First, class Second>
void run_both(First&& first, Second&& second) {
#ifdef PINSIM_WITH_TBB
  if (available_threads() > 1) {
    tbb::task_group_context own(tbb::task_group_context::isolated);
    tbb::task_group beside(own);
    beside.run([&] { second(); });
    try {
      first();
    } catch (...) {
      beside.cancel();
      try {
        beside.wait();
      } catch (...) {  // (first()'s exception is the one reported)
      }
      throw;
    }
    beside.wait();
    return;
  }
#endif
  first();
  second();
}

/// Runs f() so that a thread waiting in it for the chunks of its loops takes no task from
/// outside it (oneTBB's isolate): for work that another task spins on while it runs, which
/// must not end up waiting beneath that very task on its own thread.
template <class F>
void isolated(F&& f) {
#ifdef PINSIM_WITH_TBB
  tbb::this_task_arena::isolate(f);
#else
  f();
#endif
}

}  // namespace pinsim
