// Starting other programs (argv, no shell) and waiting for them: the Slurm driver's commands
// and the batch grader's `pinsim grade` children. The grading sandbox starts its workers
// itself (grading/sandbox.cpp), with its own limits and file descriptors.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <string>
#include <vector>

namespace pinsim {

/// Where a child's standard output and error go.
enum class ChildOutput {
  Inherit,  ///< both stay the parent's
  Discard,  ///< stdout to /dev/null; stderr stays the parent's
  Capture,  ///< stdout and stderr together into a pipe: Child::out
};

/// A started child.
struct Child {
  pid_t pid = -1;
  int out = -1;  ///< with ChildOutput::Capture, the pipe's read end (the caller closes it)
};

/// Starts argv[0] (a path, or a name searched on PATH) with arguments argv. A child that
/// cannot run the program exits with 127. Throws std::runtime_error if no pipe or process can be
/// made.
Child start_child(const std::vector<std::string>& argv, ChildOutput output);

/// Waits for child `pid`; its exit code, or -1 if it did not exit normally.
int wait_child(pid_t pid);

/// What a finished child printed, and how it ended.
struct Captured {
  int code = -1;       ///< exit code; -1 if it did not exit normally, 127 if it could not start
  std::string output;  ///< its stdout and stderr together
};

/// Runs argv (no shell) to its end, capturing stdout and stderr together.
Captured capture(const std::vector<std::string>& argv);

/// Waits for any child of this process; its pid, or -1 when there is none left. With `stop`,
/// also returns 0 as soon as *stop is non-zero (a stop signal, polled every 20 ms).
pid_t wait_any_child(const std::atomic<int>* stop = nullptr);

}  // namespace pinsim
