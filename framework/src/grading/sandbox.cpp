#include "grading/sandbox.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <stdexcept>

#include "core/clock.hpp"
#include "core/format.hpp"
#include "grading/sandbox_fallback.hpp"
#include "grading/text.hpp"

namespace fs = std::filesystem;

namespace pinsim::grading {
namespace {

bool g_unsafe = false;
bool g_probing = false;  // bubblewrap is being tried: steps are made with it

// AddressSanitizer (the asan preset) reserves terabytes of address space for its shadow
// memory when a program starts, so an address-space limit (RLIMIT_AS) would stop every
// sanitized program of a step (the worker is this program) before main. Built with it, the
// sandbox sets no RLIMIT_AS and limits memory with ASan's allocator instead: an allocation
// above the limit fails (as it would under RLIMIT_AS) and a process whose resident memory
// passes it is stopped. Programs of the step built without ASan (a compiler) then have no
// memory limit but the private /tmp's size: the asan build tests pinsim, it does not grade.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAddressSanitizer = true;
#else
constexpr bool kAddressSanitizer = false;
#endif
#else
constexpr bool kAddressSanitizer = false;
#endif

/// ASAN_OPTIONS for a step of an ASan build: the grader's own, then the memory limit. A
/// step's crashes are the submission's: they end the process by their signal, as in any
/// other build (ASan would report them and exit 1), and its leaks are not pinsim's.
std::string asan_options(const SandboxLimits& l) {
  const char* own = std::getenv("ASAN_OPTIONS");
  const std::string mb = std::to_string(static_cast<long long>(std::ceil(l.memory_mb)));
  return (own && *own ? std::string(own) + ":" : std::string()) + "hard_rss_limit_mb=" + mb +
         ":max_allocation_size_mb=" + mb +
         ":allocator_may_return_null=1:detect_leaks=0:handle_segv=0:handle_sigbus=0"
         ":handle_sigfpe=0:handle_sigill=0";
}

// Root grades as a uid of its own, unused by any account: 200000 + (pid mod 100000), one per
// grader process (as IOI's isolate gives each box its own uid). RLIMIT_NPROC counts the
// processes of a uid, so a fork bomb in one grade cannot starve a grade running beside it.
constexpr uid_t kSandboxUidBase = 200000;

std::string bwrap_program() {
  // The test suite points this at a missing program to prove the grader refuses to grade.
  const char* e = std::getenv("PINSIM_BWRAP");
  return e && *e ? e : "/usr/bin/bwrap";
}

/// Processes the grader's own uid has now (RLIMIT_NPROC counts them all when not root).
int own_process_count() {
  int n = 0;
  const uid_t me = ::getuid();
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/proc", ec)) {
    struct stat st {};
    if (std::isdigit(static_cast<unsigned char>(e.path().filename().string()[0])) &&
        ::stat(e.path().c_str(), &st) == 0 && st.st_uid == me)
      ++n;
  }
  return n;
}

void set_limit(int resource, rlim_t soft, rlim_t hard) {
  rlimit rl{soft, hard};
  ::setrlimit(resource, &rl);
}

/// Whether a folder holding a mount point must be made (readable) in the sandbox: not /tmp
/// itself (a 1777 tmpfs already) and nothing in the read-only /usr, except under /usr/local
/// (a tmpfs there); a folder under /tmp, such as a build tree there, like any other.
bool needs_dir(const fs::path& p) {
  const std::string s = p.string();
  if (s == "/tmp" || s == "/usr" || s == "/usr/local") return false;
  return s.rfind("/usr/", 0) != 0 || s.rfind("/usr/local/", 0) == 0;
}

/// The bubblewrap command line for one step.
std::vector<std::string> bwrap_args(const SandboxSpec& spec, const std::vector<std::string>& argv) {
  const auto [uid, gid] = sandbox_ids();
  const bool root = ::geteuid() == 0;
  std::vector<std::string> a = {bwrap_program(), "--die-with-parent",   "--new-session",
                                "--unshare-pid", "--unshare-net",       "--unshare-ipc",
                                "--unshare-uts", "--unshare-cgroup-try"};
  if (!root) {
    // Unprivileged: a user namespace maps the grader's uid; no nested namespaces.
    a.insert(a.end(), {"--unshare-user", "--disable-userns", "--uid", std::to_string(uid), "--gid",
                       std::to_string(gid)});
  }
  // The system's programs and libraries, read-only; nothing of /etc but what the compiler
  // and the dynamic loader need.
  a.insert(a.end(), {"--ro-bind", "/usr", "/usr"});
  for (const char* d : {"bin", "lib", "lib64", "sbin"}) {
    const fs::path p = fs::path("/") / d;
    std::error_code ec;
    if (fs::is_symlink(p, ec))
      a.insert(a.end(), {"--symlink", fs::read_symlink(p, ec).string(), p.string()});
    else if (fs::is_directory(p, ec))
      a.insert(a.end(), {"--ro-bind", p.string(), p.string()});
  }
  a.insert(a.end(), {"--ro-bind-try", "/etc/alternatives", "/etc/alternatives", "--ro-bind-try",
                     "/etc/ld.so.cache", "/etc/ld.so.cache"});
  // Locally installed software (an installed pinsim and its reference plugins) is hidden.
  std::error_code ec;
  if (fs::is_directory("/usr/local", ec)) a.insert(a.end(), {"--tmpfs", "/usr/local"});
  a.insert(a.end(), {"--proc", "/proc", "--dev", "/dev", "--perms", "1777", "--size",
                     std::to_string(static_cast<long long>(spec.limits.tmp_mb * 1048576.0)),
                     "--tmpfs", "/tmp"});
  // Folders that hold mount points, readable by the sandbox's uid (bwrap would make them 0700).
  std::vector<std::string> parents;
  for (const auto& m : spec.mounts)
    for (fs::path p = fs::path(m.inside).parent_path(); !m.inside.empty() && p != p.root_path();
         p = p.parent_path())
      if (needs_dir(p)) parents.push_back(p.string());
  std::sort(parents.begin(), parents.end());
  parents.erase(std::unique(parents.begin(), parents.end()), parents.end());
  for (const auto& p : parents) a.insert(a.end(), {"--perms", "0755", "--dir", p});
  for (const auto& m : spec.mounts) {
    if (m.inside.empty()) {  // a mask: an empty tmpfs over a host path
      std::error_code e2;
      if (fs::is_directory(m.host, e2)) a.insert(a.end(), {"--tmpfs", m.host});
      continue;
    }
    a.insert(a.end(), {m.writable ? "--bind" : "--ro-bind", m.host, m.inside});
  }
  a.insert(a.end(),
           {"--chdir", spec.cwd, "--clearenv", "--setenv", "PATH", "/usr/bin:/bin", "--setenv",
            "HOME", "/tmp", "--setenv", "TMPDIR", "/tmp", "--setenv", "LANG", "C.UTF-8"});
  if (kAddressSanitizer) {
    a.insert(a.end(), {"--setenv", "ASAN_OPTIONS", asan_options(spec.limits)});
    if (const char* u = std::getenv("UBSAN_OPTIONS"))
      a.insert(a.end(), {"--setenv", "UBSAN_OPTIONS", u});
  }
  a.insert(a.end(), {"--info-fd", "4", "--"});
  if (root) {
    // Root: bubblewrap sets up the namespaces privileged; the command itself runs as the sandbox
    // uid, with no capabilities (a uid change from 0 clears them).
    a.insert(a.end(), {"/usr/bin/setpriv", "--reuid=" + std::to_string(uid),
                       "--regid=" + std::to_string(gid), "--clear-groups", "--"});
  }
  a.insert(a.end(), argv.begin(), argv.end());
  return a;
}

/// Unsafe mode: the inside paths of argv mapped back to the host's.
std::vector<std::string> host_args(const SandboxSpec& spec, std::vector<std::string> argv) {
  for (auto& s : argv)
    for (const auto& m : spec.mounts)
      if (!m.inside.empty() && s.rfind(m.inside, 0) == 0) {
        s = m.host + s.substr(m.inside.size());
        break;
      }
  return argv;
}

[[noreturn]] void child(const std::vector<std::string>& args, const SandboxSpec& spec, int out_w,
                        int chan_w, int info_w, const std::string& cwd,
                        const fallback::Confinement* confine) {
  if (confine != nullptr) {
    // The fallback: its own session (no terminal, its own process group) and killed with
    // the grader (bubblewrap's --new-session and --die-with-parent).
    ::setsid();
  } else {
    ::setpgid(0, 0);
  }
  sigset_t none;
  sigemptyset(&none);
  ::sigprocmask(SIG_SETMASK, &none, nullptr);
  for (int s : {SIGPIPE, SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGCHLD}) ::signal(s, SIG_DFL);
  const int devnull = ::open("/dev/null", O_RDONLY);
  ::dup2(devnull, STDIN_FILENO);
  ::dup2(out_w, STDOUT_FILENO);
  ::dup2(out_w, STDERR_FILENO);
  // Descriptors 3 (channel) and 4 (bwrap's info) are placed with a detour through high
  // numbers, so that no dup2 overwrites a source still needed.
  const int chan_hi = chan_w >= 0 ? ::fcntl(chan_w, F_DUPFD, 100) : -1;
  const int info_hi = info_w >= 0 ? ::fcntl(info_w, F_DUPFD, 100) : -1;
  if (chan_hi >= 0) ::dup2(chan_hi, 3);
  if (info_hi >= 0) ::dup2(info_hi, 4);
  ::close_range(5, ~0u, 0);
  const SandboxLimits& l = spec.limits;
  const auto cpu = static_cast<rlim_t>(std::ceil(l.cpu_seconds));
  set_limit(RLIMIT_CPU, cpu, cpu + 1);
  const auto mem = static_cast<rlim_t>(l.memory_mb * 1048576.0);
  if (!kAddressSanitizer) set_limit(RLIMIT_AS, mem, mem);
  const auto fsize = static_cast<rlim_t>(l.file_mb * 1048576.0);
  set_limit(RLIMIT_FSIZE, fsize, fsize);
  set_limit(RLIMIT_NOFILE, static_cast<rlim_t>(l.open_files), static_cast<rlim_t>(l.open_files));
  set_limit(RLIMIT_CORE, 0, 0);
  // Root's own processes are not counted against it, the sandbox uid's are; an unprivileged
  // grader's uid already owns some, which count too.
  const int nproc = l.processes + (::geteuid() == 0 ? 0 : own_process_count());
  set_limit(RLIMIT_NPROC, static_cast<rlim_t>(nproc), static_cast<rlim_t>(nproc));
  if (!cwd.empty() && ::chdir(cwd.c_str()) != 0) {
    const std::string msg =
        "cannot enter the step's folder " + cwd + ": " + std::strerror(errno) + "\n";
    [[maybe_unused]] const auto w = ::write(STDERR_FILENO, msg.data(), msg.size());
    ::_exit(126);
  }
  std::vector<char*> c;
  for (const auto& s : args) c.push_back(const_cast<char*>(s.c_str()));
  c.push_back(nullptr);
  if (confine != nullptr) {
    if (const char* why = confine->apply(); why[0] != '\0') {
      [[maybe_unused]] const auto w = ::write(STDERR_FILENO, why, std::strlen(why));
      ::_exit(126);
    }
    ::execve(c[0], c.data(), confine->envp());
  } else {
    ::execv(c[0], c.data());
  }
  const std::string msg = "cannot start " + args[0] + ": " + std::strerror(errno) + "\n";
  [[maybe_unused]] const auto w = ::write(STDERR_FILENO, msg.data(), msg.size());
  ::_exit(127);
}

/// Reads bwrap's info JSON ({"child-pid": N, ...}) for the host pid of the sandbox's init.
pid_t read_inner_pid(int fd, double timeout) {
  std::string text;
  const double end = steady_seconds() + timeout;
  while (text.find('}') == std::string::npos) {
    const double left = end - steady_seconds();
    if (left <= 0) break;
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left * 1000) + 1) <= 0) break;
    char buf[512];
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n <= 0) break;
    text.append(buf, static_cast<std::size_t>(n));
    if (text.size() > 8192) break;
  }
  const auto k = text.find("\"child-pid\"");
  if (k == std::string::npos) return -1;
  const auto colon = text.find(':', k);
  if (colon == std::string::npos) return -1;
  return static_cast<pid_t>(std::atol(text.c_str() + colon + 1));
}

/// The fallback's sweep after a step: every process of its uid, its private folder, and
/// where Landlock did not keep the uid out of them, its files in world-writable folders.
void sweep_step(Sandboxed& s) {
  if (!s.fallback) return;
  s.fallback = false;
  const uid_t uid = sandbox_ids().first;
  fallback::kill_uid(uid);
  if (!s.tmp.empty()) {
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(
             s.tmp, fs::directory_options::skip_permission_denied, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
      if (fs::is_directory(it->symlink_status(ec))) ::chmod(it->path().c_str(), 0700);
    fs::remove_all(s.tmp, ec);
    s.tmp.clear();
  }
  if (fallback::support().landlock_abi == 0) fallback::remove_uid_files(uid, s.kept);
}

}  // namespace

std::string StepEnd::failure(const SandboxLimits& limits) const {
  if (timed_out)
    return "did not finish within the wall-clock limit of " + num(limits.wall_seconds) +
           " s (an infinite loop, a deadlock or a sleep?) and was killed";
  int sig = signal;
  // bubblewrap reports a command killed by signal s as exit status 128 + s.
  if (sig == 0 && exited && exit_code > 128 && exit_code < 128 + 65) sig = exit_code - 128;
  if (sig == SIGXCPU || sig == SIGKILL)
    return "exceeded the CPU-time limit of " + num(limits.cpu_seconds) + " s and was killed";
  if (sig == SIGSEGV) return "crashed with a segmentation fault (SIGSEGV)";
  if (sig == SIGBUS) return "crashed with a bus error (SIGBUS)";
  if (sig == SIGFPE) return "crashed with a floating-point exception (SIGFPE)";
  if (sig == SIGXFSZ)
    return "wrote a file larger than the limit of " + num(limits.file_mb) + " MiB (SIGXFSZ)";
  if (sig == SIGABRT)
    return "aborted (SIGABRT): an exception escaped, an assertion failed, or memory ran out "
           "(limit " +
           num(limits.memory_mb) + " MiB)";
  if (sig != 0) return std::string("was killed by signal ") + ::strsignal(sig);
  if (exited && exit_code != 0) return "exited with status " + std::to_string(exit_code);
  if (!exited) return "ended abnormally";
  return "";
}

void set_unsafe_no_sandbox(bool unsafe) { g_unsafe = unsafe; }
bool unsafe_no_sandbox() { return g_unsafe; }

std::pair<uid_t, gid_t> sandbox_ids() {
  if (::geteuid() == 0) {
    static const uid_t id = kSandboxUidBase + static_cast<uid_t>(::getpid()) % 100000;
    return {id, id};
  }
  return {::getuid(), ::getgid()};
}

namespace {

/// Whether this process may make the namespaces a sandbox needs: "" if so, else the error of
/// unshare(2) (Docker's default seccomp profile and capabilities refuse them).
std::string namespaces_refused() {
  const pid_t pid = ::fork();
  if (pid < 0) return std::string("fork: ") + std::strerror(errno);
  if (pid == 0) {
    int flags = CLONE_NEWNS | CLONE_NEWPID | CLONE_NEWNET | CLONE_NEWIPC | CLONE_NEWUTS;
    if (::geteuid() != 0) flags |= CLONE_NEWUSER;
    ::_exit(::unshare(flags) == 0 ? 0 : (errno & 0x7f) + 1);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return "";
  const int err = WIFEXITED(status) ? WEXITSTATUS(status) - 1 : EPERM;
  return std::string("unshare of the sandbox's namespaces: ") + std::strerror(err);
}

struct Status {
  SandboxMode mode = SandboxMode::None;
  std::string why_not;  ///< mode None: why no sandbox can be made
  std::string refused;  ///< mode Fallback: why namespaces cannot be used
};

/// A trivial step in bubblewrap: "" if it ran.
std::string bwrap_works() {
  std::error_code ec;
  const std::string prog = bwrap_program();
  if (!fs::exists(prog, ec)) return prog + " not found (install Debian's bubblewrap package)";
  SandboxSpec spec;
  spec.limits.wall_seconds = 20;
  StepOutput r;
  try {
    r = run_sandboxed({"/usr/bin/true"}, spec, 2000, 0);
  } catch (const std::exception& e) {
    return e.what();
  }
  if (r.end.exited && r.end.exit_code == 0) return "";
  return "bubblewrap could not make a sandbox (" + r.end.failure(spec.limits) + "): " + r.printed;
}

const Status& status() {
  static const Status st = [] {
    Status s;
    const bool was = g_unsafe;
    g_unsafe = false;
    const std::string refused = namespaces_refused();
    if (refused.empty()) {
      g_probing = true;
      s.why_not = bwrap_works();
      g_probing = false;
      s.mode = s.why_not.empty() ? SandboxMode::Namespaces : SandboxMode::None;
    } else if (const auto& f = fallback::support(); f.usable) {
      s.mode = SandboxMode::Fallback;
      s.refused = refused;
      // Orphans of a step (a double fork) come to the grader, which reaps them; and nothing
      // of an earlier grader that had this uid may still run.
      ::prctl(PR_SET_CHILD_SUBREAPER, 1);
      fallback::kill_uid(sandbox_ids().first);
    } else {
      s.why_not = "namespaces are refused here (" + refused + ") and the fallback sandbox " +
                  "cannot be used: " + f.why_not;
    }
    g_unsafe = was;
    return s;
  }();
  return st;
}

}  // namespace

SandboxMode sandbox_mode() { return g_unsafe ? SandboxMode::Unsafe : status().mode; }

const char* sandbox_mode_name(SandboxMode mode) {
  switch (mode) {
    case SandboxMode::Namespaces:
      return "bubblewrap";
    case SandboxMode::Fallback:
      return "fallback";
    case SandboxMode::Unsafe:
    case SandboxMode::None:
      return "none";
  }
  return "none";
}

std::string sandbox_description() {
  const uid_t uid = sandbox_ids().first;
  switch (sandbox_mode()) {
    case SandboxMode::Namespaces:
      return std::string("bubblewrap: new PID, mount, network, IPC and UTS namespaces; ") +
             (::geteuid() == 0
                  ? "unprivileged uid " + std::to_string(uid) + " of its own, no capabilities"
                  : std::string("a user namespace mapping the grader's uid")) +
             "; a private /tmp; rlimits; the sandbox's processes killed after each step";
    case SandboxMode::Fallback:
      return "fallback, because namespaces are refused here (" + status().refused +
             "): " + fallback::describe(uid);
    case SandboxMode::Unsafe:
      return "none (--unsafe-no-sandbox): rlimits, process groups and the wall-clock limit only";
    case SandboxMode::None:
      break;
  }
  return "none: " + status().why_not;
}

const std::string& sandbox_unavailable() {
  static const std::string empty;
  return status().mode == SandboxMode::None ? status().why_not : empty;
}

Sandboxed start_sandboxed(const std::vector<std::string>& argv, const SandboxSpec& spec) {
  const bool fallback = !g_unsafe && !g_probing && status().mode == SandboxMode::Fallback;
  const bool bwrap = !g_unsafe && !fallback;
  int out[2], info[2] = {-1, -1}, chan[2] = {-1, -1};
  if (::pipe2(out, O_CLOEXEC) != 0)
    throw std::runtime_error("pipe: " + std::string(std::strerror(errno)));
  if (bwrap && ::pipe2(info, O_CLOEXEC) != 0)
    throw std::runtime_error("pipe: " + std::string(std::strerror(errno)));
  if (spec.channel && ::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, chan) != 0)
    throw std::runtime_error("socketpair: " + std::string(std::strerror(errno)));
  std::vector<std::string> args = bwrap ? bwrap_args(spec, argv) : host_args(spec, argv);
  if (g_unsafe && kAddressSanitizer)  // the memory limit, as bwrap_args sets it in a sandbox
    args.insert(args.begin(), {"/usr/bin/env", "ASAN_OPTIONS=" + asan_options(spec.limits)});
  std::string cwd;
  if (!bwrap) cwd = host_args(spec, {spec.cwd})[0];
  // The fallback's private folder (HOME, TMPDIR, and the working folder where the step
  // would have had the sandbox's /tmp), owned by the step's uid alone.
  std::string tmp;
  std::unique_ptr<fallback::Confinement> confine;
  if (fallback) {
    const char* base = std::getenv("TMPDIR");
    tmp = std::string(base && *base ? base : "/tmp") + "/pinsim-step-XXXXXX";
    if (::mkdtemp(tmp.data()) == nullptr)
      throw std::runtime_error("cannot make the step's folder " + tmp + ": " +
                               std::strerror(errno));
    const auto [uid, gid] = sandbox_ids();
    if (::chown(tmp.c_str(), uid, gid) != 0 || ::chmod(tmp.c_str(), 0700) != 0)
      throw std::runtime_error("cannot give the step's folder " + tmp + " to uid " +
                               std::to_string(uid) + ": " + std::strerror(errno));
    if (spec.cwd == "/tmp") cwd = tmp;
    std::vector<std::string> env;
    if (kAddressSanitizer) {
      env.push_back("ASAN_OPTIONS=" + asan_options(spec.limits));
      if (const char* u = std::getenv("UBSAN_OPTIONS"))
        env.push_back(std::string("UBSAN_OPTIONS=") + u);
    }
    confine = std::make_unique<fallback::Confinement>(spec, uid, gid, tmp, env);
  }
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork: " + std::string(std::strerror(errno)));
  if (pid == 0)
    child(args, spec, out[1], chan[1], info[1], bwrap ? std::string() : cwd, confine.get());
  ::setpgid(pid, pid);  // also here, so that a kill right after fork reaches the group
  ::close(out[1]);
  if (info[1] >= 0) ::close(info[1]);
  if (chan[1] >= 0) ::close(chan[1]);
  Sandboxed s;
  s.pid = pid;
  s.output_fd = out[0];
  s.channel_fd = chan[0];
  s.fallback = fallback;
  s.tmp = tmp;
  for (const auto& m : spec.mounts)
    if (m.writable && !m.inside.empty()) s.kept.push_back(m.host);
  ::fcntl(s.output_fd, F_SETFL, O_NONBLOCK);
  if (info[0] >= 0) {
    s.inner = read_inner_pid(info[0], 10.0);
    ::close(info[0]);
  }
  return s;
}

StepEnd kill_and_reap(Sandboxed& s, bool timed_out) {
  StepEnd end;
  end.timed_out = timed_out;
  if (s.pid > 0) {
    int status = 0;
    pid_t w = ::waitpid(s.pid, &status, WNOHANG);
    if (w == 0) {
      // The sandbox's init first: its death takes every process of the PID namespace with it,
      // and bubblewrap then exits by itself.
      if (s.inner > 0) ::kill(s.inner, SIGKILL);
      for (int i = 0; i < 200 && w == 0; ++i) {
        ::usleep(5000);
        w = ::waitpid(s.pid, &status, WNOHANG);
      }
      if (w == 0) {
        ::kill(-s.pid, SIGKILL);
        ::kill(s.pid, SIGKILL);
        w = ::waitpid(s.pid, &status, 0);
      }
    }
    ::kill(-s.pid, SIGKILL);  // anything left in the process group (unsafe mode)
    if (w == s.pid) {
      if (WIFEXITED(status)) {
        end.exited = true;
        end.exit_code = WEXITSTATUS(status);
      } else if (WIFSIGNALED(status)) {
        end.signal = WTERMSIG(status);
      }
    }
    s.pid = -1;
  }
  sweep_step(s);
  if (s.output_fd >= 0) ::close(s.output_fd);
  if (s.channel_fd >= 0) ::close(s.channel_fd);
  s.output_fd = s.channel_fd = -1;
  return end;
}

StepOutput run_sandboxed(const std::vector<std::string>& argv, const SandboxSpec& spec,
                         std::size_t keep_head, std::size_t keep_tail) {
  StepOutput r;
  const double start = steady_seconds();
  Sandboxed s = start_sandboxed(argv, spec);
  BoundedText printed(keep_head, keep_tail);
  bool timed_out = false, eof = false;
  int status = 0;
  pid_t w = 0;
  for (;;) {
    if (!eof) {
      pollfd p{s.output_fd, POLLIN, 0};
      ::poll(&p, 1, 50);
      char buf[65536];
      for (;;) {
        const ssize_t n = ::read(s.output_fd, buf, sizeof buf);
        if (n > 0) {
          printed.append(buf, static_cast<std::size_t>(n));
          continue;
        }
        if (n == 0) eof = true;
        break;
      }
    } else {
      ::usleep(10000);
    }
    w = ::waitpid(s.pid, &status, WNOHANG);
    if (w == s.pid && eof) break;
    if (w == s.pid) {  // exited; read what is left without waiting for stray writers
      char buf[65536];
      ssize_t n;
      while ((n = ::read(s.output_fd, buf, sizeof buf)) > 0)
        printed.append(buf, static_cast<std::size_t>(n));
      break;
    }
    if (steady_seconds() - start > spec.limits.wall_seconds) {
      timed_out = true;
      break;
    }
  }
  if (w == s.pid) {
    if (WIFEXITED(status)) {
      r.end.exited = true;
      r.end.exit_code = WEXITSTATUS(status);
    } else if (WIFSIGNALED(status)) {
      r.end.signal = WTERMSIG(status);
    }
    s.pid = -1;
    sweep_step(s);
    ::close(s.output_fd);
    s.output_fd = -1;
    if (s.channel_fd >= 0) ::close(s.channel_fd);
  } else {
    r.end = kill_and_reap(s, timed_out);
  }
  r.printed = printed.text();
  r.seconds = steady_seconds() - start;
  return r;
}

}  // namespace pinsim::grading
