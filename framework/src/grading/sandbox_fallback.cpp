#include "grading/sandbox_fallback.hpp"

#include <fcntl.h>
#include <grp.h>
#include <linux/audit.h>
#include <linux/filter.h>
#include <linux/seccomp.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace pinsim::grading::fallback {
namespace {

// Landlock's ABI (linux/landlock.h), spelled out here because a build machine's kernel
// headers may predate the rights a newer running kernel offers (the ABI is stable).
#ifndef SYS_landlock_create_ruleset
#define SYS_landlock_create_ruleset 444
#define SYS_landlock_add_rule 445
#define SYS_landlock_restrict_self 446
#endif
constexpr uint32_t kCreateRulesetVersion = 1u << 0;
constexpr uint32_t kRulePathBeneath = 1;
constexpr uint64_t kFsExecute = 1ull << 0, kFsWriteFile = 1ull << 1, kFsReadFile = 1ull << 2,
                   kFsReadDir = 1ull << 3, kFsRemoveDir = 1ull << 4, kFsRemoveFile = 1ull << 5,
                   kFsMakeChar = 1ull << 6, kFsMakeDir = 1ull << 7, kFsMakeReg = 1ull << 8,
                   kFsMakeSock = 1ull << 9, kFsMakeFifo = 1ull << 10, kFsMakeBlock = 1ull << 11,
                   kFsMakeSym = 1ull << 12, kFsRefer = 1ull << 13, kFsTruncate = 1ull << 14,
                   kFsIoctlDev = 1ull << 15;
constexpr uint64_t kNetBindTcp = 1ull << 0, kNetConnectTcp = 1ull << 1;
constexpr uint64_t kScopeAbstractUnix = 1ull << 0, kScopeSignal = 1ull << 1;
/// The rights a rule on a file (not a folder) may carry.
constexpr uint64_t kFileRights =
    kFsExecute | kFsWriteFile | kFsReadFile | kFsTruncate | kFsIoctlDev;
constexpr uint64_t kReadOnly = kFsExecute | kFsReadFile | kFsReadDir;
constexpr uint64_t kReadWrite = kReadOnly | kFsWriteFile | kFsRemoveDir | kFsRemoveFile |
                                kFsMakeDir | kFsMakeReg | kFsMakeSym | kFsMakeFifo | kFsMakeSock |
                                kFsRefer | kFsTruncate;

struct RulesetAttr {
  uint64_t handled_access_fs;
  uint64_t handled_access_net;  // ABI 4
  uint64_t scoped;              // ABI 6
};
struct __attribute__((packed)) PathBeneathAttr {
  uint64_t allowed_access;
  int32_t parent_fd;
};

/// Every file-system right this ABI knows (all of them are denied unless a rule allows).
uint64_t handled_fs(int abi) {
  uint64_t all = kFsExecute | kFsWriteFile | kFsReadFile | kFsReadDir | kFsRemoveDir |
                 kFsRemoveFile | kFsMakeChar | kFsMakeDir | kFsMakeReg | kFsMakeSock | kFsMakeFifo |
                 kFsMakeBlock | kFsMakeSym;
  if (abi >= 2) all |= kFsRefer;
  if (abi >= 3) all |= kFsTruncate;
  if (abi >= 5) all |= kFsIoctlDev;
  return all;
}

#if defined(__x86_64__)
constexpr uint32_t kAuditArch = AUDIT_ARCH_X86_64;
#elif defined(__aarch64__)
constexpr uint32_t kAuditArch = AUDIT_ARCH_AARCH64;
#else
constexpr uint32_t kAuditArch = 0;  // no filter on other architectures
#endif

/// The seccomp filter: another architecture's calls kill the process (no way around the
/// numbers below); socket() only for AF_UNIX; the listed calls fail with EPERM.
std::vector<sock_filter> seccomp_program() {
  std::vector<sock_filter> f;
  const auto stmt = [&](uint16_t code, uint32_t k) { f.push_back(BPF_STMT(code, k)); };
  const auto jump = [&](uint32_t k, uint8_t jt, uint8_t jf) {
    f.push_back(BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, k, jt, jf));
  };
  stmt(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, arch));
  jump(kAuditArch, 1, 0);
  stmt(BPF_RET | BPF_K, SECCOMP_RET_KILL_PROCESS);
  stmt(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, nr));
#if defined(__x86_64__)
  // The x32 numbering (bit 30) would reach the same calls under other numbers.
  f.push_back(BPF_JUMP(BPF_JMP | BPF_JGE | BPF_K, 0x40000000u, 0, 1));
  stmt(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | ENOSYS);
#endif
  // socket(): local sockets only (the low word of the family argument).
  jump(SYS_socket, 0, 4);
  stmt(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, args[0]));
  jump(AF_UNIX, 0, 1);
  stmt(BPF_RET | BPF_K, SECCOMP_RET_ALLOW);
  stmt(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EACCES);
  // io_uring can open sockets and files behind the filter's back; the rest reach kernel
  // features a submission has no use for.
  for (const long nr :
       {SYS_io_uring_setup, SYS_io_uring_enter, SYS_io_uring_register, SYS_bpf, SYS_perf_event_open,
        SYS_userfaultfd, SYS_keyctl, SYS_add_key, SYS_request_key, SYS_unshare, SYS_setns,
        SYS_mount, SYS_umount2, SYS_pivot_root}) {
    jump(static_cast<uint32_t>(nr), 0, 1);
    stmt(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EPERM);
  }
  stmt(BPF_RET | BPF_K, SECCOMP_RET_ALLOW);
  return f;
}

struct Probed {
  Support support;
  std::vector<sock_filter> filter;
};

/// Reads the real uid and the state of process `pid` from /proc; false if it is gone.
bool process_info(const std::string& pid, uid_t& uid, char& state, pid_t& ppid) {
  std::ifstream st("/proc/" + pid + "/stat");
  std::string stat;
  if (!std::getline(st, stat)) return false;
  const auto close = stat.rfind(')');
  if (close == std::string::npos || close + 4 >= stat.size()) return false;
  state = stat[close + 2];
  ppid = static_cast<pid_t>(std::atol(stat.c_str() + close + 4));
  std::ifstream status("/proc/" + pid + "/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind("Uid:", 0) == 0) {
      uid = static_cast<uid_t>(std::strtoul(line.c_str() + 4, nullptr, 10));
      return true;
    }
  return false;
}

/// Live processes of `uid`; zombies of it that are this process's children are reaped.
int alive_and_reap(uid_t uid) {
  int live = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/proc", ec)) {
    const std::string name = e.path().filename().string();
    if (name.empty() || !std::isdigit(static_cast<unsigned char>(name[0]))) continue;
    uid_t u = 0;
    char state = 0;
    pid_t ppid = 0;
    if (!process_info(name, u, state, ppid) || u != uid) continue;
    if (state != 'Z' && state != 'X') {
      ++live;
    } else if (ppid == ::getpid()) {
      int status = 0;
      ::waitpid(static_cast<pid_t>(std::atol(name.c_str())), &status, WNOHANG);
    }
  }
  return live;
}

bool become(uid_t uid, gid_t gid) {
  return ::setgroups(0, nullptr) == 0 && ::setresgid(gid, gid, gid) == 0 &&
         ::setresuid(uid, uid, uid) == 0;
}

const Probed& probed() {
  static const Probed p = [] {
    Probed r;
    r.filter = seccomp_program();
    Support& s = r.support;
    const long abi = ::syscall(SYS_landlock_create_ruleset, nullptr, 0, kCreateRulesetVersion);
    s.landlock_abi = abi > 0 ? static_cast<int>(abi) : 0;
    s.seccomp = kAuditArch != 0;
    if (::geteuid() != 0) {
      s.why_not =
          "the grader is not root, so it cannot run submissions as a uid of their own "
          "(that needs root, or CAP_SETUID and CAP_SETGID)";
      return r;
    }
    s.usable = true;
    return r;
  }();
  return p;
}

}  // namespace

const Support& support() { return probed().support; }

Confinement::Confinement(const SandboxSpec& spec, uid_t uid, gid_t gid, const std::string& tmp,
                         const std::vector<std::string>& env)
    : uid_(uid), gid_(gid) {
  const Support& s = support();
  if (s.landlock_abi > 0) {
    // The system's programs and libraries, read-only: /usr without /usr/local (where an
    // installed pinsim keeps its reference plugins), and /bin, /lib, ... where they are
    // folders of their own rather than links into /usr.
    std::error_code ec;
    for (const auto& e : fs::directory_iterator("/usr", ec))
      if (e.path().filename() != "local") rules_.push_back({e.path().string(), kReadOnly});
    for (const char* d : {"/bin", "/sbin", "/lib", "/lib32", "/lib64", "/libx32"})
      if (!fs::is_symlink(d, ec) && fs::is_directory(d, ec)) rules_.push_back({d, kReadOnly});
    rules_.push_back({"/etc/alternatives", kReadOnly});
    rules_.push_back({"/etc/ld.so.cache", kFsReadFile});
    rules_.push_back({"/proc", kFsReadFile | kFsReadDir});
    for (const char* d : {"/dev/null", "/dev/zero", "/dev/full"})
      rules_.push_back({d, kFsReadFile | kFsWriteFile});
    for (const char* d : {"/dev/random", "/dev/urandom"}) rules_.push_back({d, kFsReadFile});
    for (const auto& m : spec.mounts)
      if (!m.inside.empty()) rules_.push_back({m.host, m.writable ? kReadWrite : kReadOnly});
    if (!tmp.empty()) rules_.push_back({tmp, kReadWrite});
  }
  const std::string home = tmp.empty() ? "/nonexistent" : tmp;
  env_ = {"PATH=/usr/bin:/bin", "HOME=" + home, "TMPDIR=" + home, "LANG=C.UTF-8"};
  env_.insert(env_.end(), env.begin(), env.end());
  for (auto& e : env_) env_ptrs_.push_back(e.data());
  env_ptrs_.push_back(nullptr);
}

const char* Confinement::apply() const noexcept {
  const Probed& p = probed();
  const int abi = p.support.landlock_abi;
  int ruleset = -1;
  if (abi > 0) {
    // As root still, so that every rule's path can be opened.
    RulesetAttr attr{handled_fs(abi), abi >= 4 ? kNetBindTcp | kNetConnectTcp : 0,
                     abi >= 6 ? kScopeAbstractUnix | kScopeSignal : 0};
    const std::size_t size = abi >= 6 ? 24 : abi >= 4 ? 16 : 8;
    ruleset = static_cast<int>(::syscall(SYS_landlock_create_ruleset, &attr, size, 0));
    if (ruleset < 0) return "landlock_create_ruleset failed";
    for (const Rule& r : rules_) {
      const int fd = ::open(r.path.c_str(), O_PATH | O_CLOEXEC);
      if (fd < 0) continue;  // not on this machine
      struct stat st {};
      uint64_t access = r.access & handled_fs(abi);
      if (::fstat(fd, &st) == 0 && !S_ISDIR(st.st_mode)) access &= kFileRights;
      PathBeneathAttr pb{access, fd};
      const long rc = ::syscall(SYS_landlock_add_rule, ruleset, kRulePathBeneath, &pb, 0);
      ::close(fd);
      if (rc != 0) return "landlock_add_rule failed";
    }
  }
  const pid_t parent = ::getppid();
  if (!become(uid_, gid_)) return "cannot change to the sandbox's uid";
  // Killed with the grader (set after the uid change, which clears it), and not started at
  // all if the grader is already gone.
  if (::prctl(PR_SET_PDEATHSIG, SIGKILL) != 0 || ::getppid() != parent) return "the grader is gone";
  if (::prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) != 0) return "PR_SET_NO_NEW_PRIVS failed";
  if (ruleset >= 0) {
    if (::syscall(SYS_landlock_restrict_self, ruleset, 0) != 0)
      return "landlock_restrict_self failed";
    ::close(ruleset);
  }
  if (p.support.seccomp) {
    sock_fprog prog{static_cast<unsigned short>(p.filter.size()),
                    const_cast<sock_filter*>(p.filter.data())};
    if (::prctl(PR_SET_SECCOMP, SECCOMP_MODE_FILTER, &prog) != 0) return "seccomp filter failed";
  }
  return "";
}

void kill_uid(uid_t uid) {
  // Until none is left: on a loaded machine, processes killed at once (a fork bomb's) can
  // take seconds to be scheduled and exit; bounded by time, not by a count of rounds.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (true) {
    // kill(-1) as the uid itself reaches every process of it, and nothing else.
    const pid_t k = ::fork();
    if (k == 0) {
      if (become(uid, uid)) ::kill(-1, SIGKILL);
      ::_exit(0);
    }
    if (k > 0) {
      int status = 0;
      ::waitpid(k, &status, 0);
    }
    const int alive = alive_and_reap(uid);
    if (alive == 0) return;
    if (std::chrono::steady_clock::now() > until) {
      spdlog::warn("{} process(es) of the sandbox's uid {} still alive after 20 s of SIGKILL",
                   alive, uid);
      return;
    }
    ::usleep(5000);
  }
}

void remove_uid_files(uid_t uid, const std::vector<std::string>& kept) {
  std::vector<fs::path> keep;
  for (const auto& k : kept) {
    std::error_code ec;
    keep.push_back(fs::weakly_canonical(k, ec));
    if (ec) keep.back() = fs::path(k).lexically_normal();
  }
  // p is a kept folder or inside one
  auto is_kept = [&](const fs::path& p) {
    std::error_code ec;
    fs::path c = fs::weakly_canonical(p, ec);
    if (ec) c = p.lexically_normal();
    for (const auto& k : keep) {
      if (std::mismatch(k.begin(), k.end(), c.begin(), c.end()).first == k.end()) return true;
    }
    return false;
  };
  for (const char* root : {"/tmp", "/var/tmp", "/dev/shm"}) {
    std::error_code ec;
    std::vector<fs::path> found;
    for (auto it = fs::recursive_directory_iterator(
             root, fs::directory_options::skip_permission_denied, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
      struct stat st {};
      if (::lstat(it->path().c_str(), &st) != 0 || st.st_uid != uid) {
        if (it.depth() >= 3) it.disable_recursion_pending();
        continue;
      }
      if (is_kept(it->path())) {
        it.disable_recursion_pending();
        continue;
      }
      found.push_back(it->path());
      it.disable_recursion_pending();  // removed whole below
    }
    for (const auto& f : found) {
      for (auto it = fs::recursive_directory_iterator(
               f, fs::directory_options::skip_permission_denied, ec);
           !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
        if (fs::is_directory(it->symlink_status(ec))) ::chmod(it->path().c_str(), 0700);
      fs::remove_all(f, ec);
    }
  }
}

std::vector<Probe> reachable(const std::vector<Probe>& probes, uid_t uid, gid_t gid) {
  std::vector<std::string> paths;
  for (const auto& pr : probes)
    paths.push_back(pr.write ? (pr.path / (".pinsim-probe-" + std::to_string(::getpid()))).string()
                             : pr.path.string());
  const Confinement c(SandboxSpec{}, uid, gid, "");
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return probes;  // cannot tell: assume the worst
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    if (c.apply()[0] != '\0') ::_exit(126);
    for (uint32_t i = 0; i < paths.size(); ++i) {
      const int fd = probes[i].write
                         ? ::open(paths[i].c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600)
                         : ::open(paths[i].c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
      if (fd < 0) continue;
      ::close(fd);
      if (probes[i].write) ::unlink(paths[i].c_str());
      [[maybe_unused]] const auto w = ::write(fds[1], &i, sizeof i);
    }
    ::_exit(0);
  }
  ::close(fds[1]);
  std::vector<Probe> open;
  uint32_t i = 0;
  while (pid > 0 && ::read(fds[0], &i, sizeof i) == sizeof i)
    if (i < probes.size()) open.push_back(probes[i]);
  ::close(fds[0]);
  int status = 0;
  if (pid > 0) ::waitpid(pid, &status, 0);
  if (pid < 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) return probes;
  return open;
}

std::string describe(uid_t uid) {
  const Support& s = support();
  std::ostringstream o;
  o << "unprivileged uid " << uid << " owning none of the grader's files, no new privileges; ";
  if (s.landlock_abi > 0)
    o << "Landlock ABI " << s.landlock_abi
      << " (it may read only /usr without /usr/local, /etc/alternatives, /proc and what each "
         "step is given, and write only its own folders"
      << (s.landlock_abi >= 4 ? "; no TCP" : "")
      << (s.landlock_abi >= 6 ? "; no signals or abstract sockets outside" : "") << "); ";
  else
    o << "no Landlock here (file access by permissions only: the grader checks that its files "
         "are out of reach, and removes what the uid leaves in /tmp, /var/tmp and /dev/shm); ";
  o << (s.seccomp ? "seccomp (no sockets but AF_UNIX, no io_uring, bpf, perf or keyrings); "
                  : "no seccomp filter on this architecture; ");
  o << "rlimits; every process of uid " << uid
    << " killed after each step; no PID, mount or network namespace";
  return o.str();
}

}  // namespace pinsim::grading::fallback
