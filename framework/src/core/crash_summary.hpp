// summary.json for a run that dies of a signal (a plugin's segfault or abort, SIGBUS,
// SIGFPE, SIGILL): the text is rendered and its temporary file opened (with disk space
// reserved) before the run starts, and the handler only fills in the signal and the step
// with async-signal-safe calls (write, close, rename), then re-raises the signal so the exit
// status still shows it. The reserved file also takes the final summary when the disk is
// full.
#pragma once

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string_view>

namespace pinsim {

class CrashSummary {
 public:
  /// Prepares DIR/summary.json for a crash from `summary` (its status becomes "crashed"; the
  /// handler adds "steps", "signal" and "error"), opens DIR/summary.json.crash.PID with
  /// kReserve bytes of disk reserved, and installs the handlers (on an alternate stack, so a
  /// stack overflow is caught too). One at a time per process. Throws OutputError if the
  /// temporary file cannot be made.
  CrashSummary(const std::filesystem::path& dir, nlohmann::json summary);
  /// Disarms and removes the temporary file.
  ~CrashSummary();
  CrashSummary(const CrashSummary&) = delete;
  CrashSummary& operator=(const CrashSummary&) = delete;

  /// Restores the previous handlers: from here a crash leaves summary.json as it is.
  void disarm() noexcept;

  /// Disarms, then writes `bytes` into the reserved temporary file and renames it over
  /// summary.json: the final summary when writing it the usual way failed (a full disk).
  /// Returns 0 or the errno of the step that failed.
  int write_instead(std::string_view bytes) noexcept;

  /// Bytes of disk reserved for the summary.
  static constexpr long kReserve = 16384;

  /// The last completed step, for the summary written on a crash. Lock-free.
  static void set_step(uint64_t step) noexcept;
};

/// Where no summary.json can say it (a crash before a run's output folder is prepared, or a
/// run without --out): from now on a crash signal (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT)
/// first prints "pinsim: killed by SIGSEGV " followed by `line` on stderr, then kills the
/// process as before (default action), so the exit status still shows it. `line` must live
/// as long as the process (a literal); nullptr silences it. Arming a CrashSummary silences
/// it: summary.json then says what happened. Async-signal-safe handler, on the same
/// alternate stack.
void set_crash_notice(const char* line) noexcept;

}  // namespace pinsim
