// Running untrusted work in a child process with CPU-time, memory and wall-clock limits.
#pragma once

#include <string>
#include <vector>

namespace pinsim {

struct ChildLimits {
  double cpu_seconds = 10.0;   ///< RLIMIT_CPU (SIGXCPU, then SIGKILL)
  double memory_mb = 2048.0;   ///< RLIMIT_AS: address space, MiB
  double wall_seconds = 30.0;  ///< killed with SIGKILL after this much real time
};

struct ChildResult {
  bool started = false;  ///< false: fork/exec failed (see output)
  bool exited = false;   ///< exited normally (then exit_code is valid)
  int exit_code = -1;
  int signal = 0;          ///< terminating signal, or 0
  bool timed_out = false;  ///< killed for exceeding the wall-clock limit
  double wall_seconds = 0.0;
  std::string output;  ///< stdout (stderr goes to stderr_text)
  std::string stderr_text;

  /// One line saying what went wrong, or "" for a normal exit: "crashed with a
  /// segmentation fault (SIGSEGV)", "exceeded the CPU-time limit of 2 s", ...
  std::string failure(const ChildLimits& limits) const;
};

/// Runs argv[0] with arguments argv in a forked child under the limits. The child's stdout
/// and stderr go to temporary files (no pipe can fill and block). Call only from a
/// single-threaded process (it forks).
ChildResult run_limited(const std::vector<std::string>& argv, const ChildLimits& limits);

}  // namespace pinsim
