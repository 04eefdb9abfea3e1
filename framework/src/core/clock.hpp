// A monotonic clock in seconds, for timeouts and durations (never for results).
#pragma once

#include <chrono>

namespace pinsim {

/// Seconds on the steady clock since an arbitrary epoch.
inline double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace pinsim
