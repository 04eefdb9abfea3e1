// Running untrusted work (a submission's build, its plugin in the worker) in a sandbox made
// with bubblewrap (Debian's `bubblewrap`): new PID, network, IPC and UTS namespaces, a file
// system view of only what the step needs (read-only except one folder), a private /tmp, an
// unprivileged uid (one of its own when the grader runs as root), rlimits, a new session, and the
// whole process tree killed when the step ends. See docs/grading.md for the threat model.
#pragma once

#include <sys/types.h>

#include <string>
#include <utility>
#include <vector>

namespace pinsim::grading {

/// Resource limits of one sandboxed step.
struct SandboxLimits {
  double cpu_seconds = 10.0;   ///< RLIMIT_CPU per process, s (SIGXCPU, then SIGKILL)
  double memory_mb = 2048.0;   ///< RLIMIT_AS per process, MiB
  double wall_seconds = 30.0;  ///< the whole step is killed after this much real time, s
  int processes = 64;          ///< RLIMIT_NPROC: processes of the sandbox's uid
  double file_mb = 64.0;       ///< RLIMIT_FSIZE: largest file a process may write, MiB
  int open_files = 256;        ///< RLIMIT_NOFILE
  double tmp_mb = 256.0;       ///< size of the private /tmp (a tmpfs), MiB
};

/// One folder (or file) made visible inside the sandbox.
struct Mount {
  std::string host, inside;
  bool writable = false;
};

struct SandboxSpec {
  std::vector<Mount> mounts;
  std::string cwd = "/tmp";
  SandboxLimits limits;
  /// Give the process the grader's channel as file descriptor 3.
  bool channel = false;
};

/// A started sandboxed process. Its stdout and stderr both go to `output_fd` (a pipe the
/// grader drains); `channel_fd` is the grader's end of the socket (or -1).
struct Sandboxed {
  pid_t pid = -1;      ///< the process the grader forked (bwrap, or the command when unsafe)
  pid_t inner = -1;    ///< the sandbox's init as the host sees it (-1 when unknown)
  int output_fd = -1;  ///< read end: everything the step printed
  int channel_fd = -1;
  bool fallback = false;  ///< started in the fallback sandbox: its uid is swept at the end
  std::string tmp;        ///< the fallback's private folder for the step ("" otherwise)
  /// The host folders the step was given to write (its writable mounts: a source
  /// submission's build folder): what the uid keeps there is not swept after the step.
  std::vector<std::string> kept;
};

/// How a step ended.
struct StepEnd {
  bool exited = false;
  int exit_code = -1;
  int signal = 0;
  bool timed_out = false;
  /// One line for a student: "" for exit code 0, else what happened ("crashed with a
  /// segmentation fault (SIGSEGV)", "exceeded the CPU-time limit of 2 s", ...).
  std::string failure(const SandboxLimits& limits) const;
};

/// How untrusted steps are isolated here.
enum class SandboxMode {
  Namespaces,  ///< bubblewrap: PID, mount, network, IPC and UTS namespaces (docs/grading.md)
  Fallback,    ///< namespaces refused: a uid of its own, Landlock, seccomp (sandbox_fallback.hpp)
  Unsafe,      ///< --unsafe-no-sandbox: rlimits, process groups and the wall-clock limit only
  None         ///< no sandbox can be made and grading unsafely was not asked for
};

/// The mode probed once: bubblewrap if it can make a sandbox; the fallback only when it
/// cannot because namespaces are refused and the grader can change uid; else None.
SandboxMode sandbox_mode();
/// "bubblewrap", "fallback" or "none" (results.json's extra_data.sandbox.mode).
const char* sandbox_mode_name(SandboxMode mode);
/// One line saying what isolates a step in this mode, and why the fallback if it is one.
std::string sandbox_description();

/// Whether sandboxes can be made here; "" if so (bubblewrap, or the fallback where
/// namespaces are refused), else why not (bubblewrap missing, namespaces refused and the
/// grader not root, ...).
const std::string& sandbox_unavailable();

/// Grade without a sandbox (--unsafe-no-sandbox): processes still get rlimits, their own
/// process group and a wall-clock limit, but see the whole machine as the grader's user.
void set_unsafe_no_sandbox(bool unsafe);
bool unsafe_no_sandbox();

/// The uid and gid untrusted steps run as: when the grader is root, an unprivileged id of this
/// grader process's own (200000 + pid mod 100000, owned by no account); else the grader's own
/// uid (then a user namespace maps it, and only the mounts are visible).
std::pair<uid_t, gid_t> sandbox_ids();

/// Starts argv[0] (an absolute path inside the sandbox) with arguments argv. Throws
/// std::runtime_error if the process cannot be started at all.
Sandboxed start_sandboxed(const std::vector<std::string>& argv, const SandboxSpec& spec);

/// Kills every process of the step (the sandbox's init, then the process group) and reaps
/// the process the grader forked; closes the descriptors.
StepEnd kill_and_reap(Sandboxed& s, bool timed_out);

/// Waits for the step to end by itself (up to the wall-clock limit, then kills it), draining
/// its output into `output` (at most `keep_head` + `keep_tail` bytes are kept).
struct StepOutput {
  StepEnd end;
  std::string printed;  ///< sanitized, bounded
  double seconds = 0.0;
};
StepOutput run_sandboxed(const std::vector<std::string>& argv, const SandboxSpec& spec,
                         std::size_t keep_head, std::size_t keep_tail);

}  // namespace pinsim::grading
