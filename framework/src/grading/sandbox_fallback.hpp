// The sandbox where namespaces are refused (Docker's default seccomp profile and capability
// set, as on Gradescope): the step runs as an unprivileged uid of its own that owns none of
// the grader's files, with no new privileges, Landlock file-system rules where the kernel
// has Landlock (only /usr, the step's own folders and what it is given; no TCP; no signals
// or abstract sockets outside), a seccomp filter (no sockets but local ones, no io_uring,
// bpf, perf or keyrings), the step's rlimits, and every process of the uid killed when the
// step ends. It needs root (or CAP_SETUID and CAP_SETGID) to change uid. What it cannot do
// without namespaces: hide the machine's processes, give a private /tmp (without Landlock the
// uid can write world-writable folders; the grader removes what it left there) or kill what
// escaped if the grader itself is killed with SIGKILL.
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

#include "grading/sandbox.hpp"

namespace pinsim::grading::fallback {

/// What this kernel and process offer the fallback; probed once.
struct Support {
  bool usable = false;   ///< a step can be confined here
  int landlock_abi = 0;  ///< 0: no Landlock
  bool seccomp = false;  ///< the seccomp filter applies (this architecture)
  std::string why_not;   ///< when not usable
};
const Support& support();

/// One step's confinement, computed before fork: the child only makes system calls.
class Confinement {
 public:
  /// `env`: variables the step gets besides PATH, HOME, TMPDIR and LANG.
  Confinement(const SandboxSpec& spec, uid_t uid, gid_t gid, const std::string& tmp,
              const std::vector<std::string>& env = {});
  /// In the forked child, as root: become the uid, apply Landlock and seccomp. Returns "" or
  /// what failed (the child then exits 126 with it).
  const char* apply() const noexcept;
  /// The environment of the step (PATH, HOME and TMPDIR in its own folder, LANG).
  char* const* envp() const { return env_ptrs_.data(); }

 private:
  struct Rule {
    std::string path;
    uint64_t access;  ///< for a directory; a file keeps only its file rights
  };
  uid_t uid_;
  gid_t gid_;
  std::vector<Rule> rules_;
  std::vector<std::string> env_;
  std::vector<char*> env_ptrs_;
};

/// Kills every process of `uid` (as that uid, so nothing else can be hit), repeating until
/// none is left alive, and reaps the ones that became this process's children.
void kill_uid(uid_t uid);

/// Removes what `uid` left in the machine's world-writable folders (/tmp, /var/tmp,
/// /dev/shm): needed where Landlock does not keep it out of them. The folders in `kept` (the
/// ones the grader gave the step to write, such as a source submission's build folder under
/// $TMPDIR) and what is inside them stay.
void remove_uid_files(uid_t uid, const std::vector<std::string>& kept);

/// One path the grader keeps to itself, and how the probe tries it.
struct Probe {
  std::filesystem::path path;
  bool write = false;  ///< a folder: try to create a file in it; else: try to open it
};
/// The probes that succeeded as `uid` under the confinement of a step: paths the submission
/// could read (or write). Empty when the grader's files are out of its reach.
std::vector<Probe> reachable(const std::vector<Probe>& probes, uid_t uid, gid_t gid);

/// One line for results.json and the log: what the fallback gives here.
std::string describe(uid_t uid);

}  // namespace pinsim::grading::fallback
