#include "grading/child_process.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>

namespace pinsim {
namespace {

std::string slurp_fd(int fd) {
  std::string out;
  ::lseek(fd, 0, SEEK_SET);
  char buf[8192];
  ssize_t n;
  while ((n = ::read(fd, buf, sizeof buf)) > 0) out.append(buf, static_cast<std::size_t>(n));
  return out;
}

int temp_fd() {
  char name[] = "/tmp/pinsim-child-XXXXXX";
  const int fd = ::mkstemp(name);
  if (fd >= 0) ::unlink(name);
  return fd;
}

std::string fmt_seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", s);
  return buf;
}

}  // namespace

std::string ChildResult::failure(const ChildLimits& limits) const {
  if (!started) return "could not start: " + stderr_text;
  if (timed_out)
    return "did not finish within the wall-clock limit of " + fmt_seconds(limits.wall_seconds) +
           " s (an infinite loop or a deadlock?) and was killed";
  if (signal == SIGXCPU || (signal == SIGKILL && !timed_out))
    return "exceeded the CPU-time limit of " + fmt_seconds(limits.cpu_seconds) + " s";
  if (signal == SIGSEGV) return "crashed with a segmentation fault (SIGSEGV)";
  if (signal == SIGBUS) return "crashed with a bus error (SIGBUS)";
  if (signal == SIGFPE) return "crashed with a floating-point exception (SIGFPE)";
  if (signal == SIGABRT)
    return "aborted (SIGABRT): an exception escaped, an assertion failed, or memory ran out "
           "(limit " +
           fmt_seconds(limits.memory_mb) + " MiB)";
  if (signal != 0) return std::string("killed by signal ") + ::strsignal(signal);
  return "";
}

ChildResult run_limited(const std::vector<std::string>& argv, const ChildLimits& limits) {
  ChildResult r;
  const int out_fd = temp_fd(), err_fd = temp_fd();
  if (out_fd < 0 || err_fd < 0) {
    r.stderr_text = "cannot create temporary files";
    return r;
  }
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);

  std::fflush(nullptr);
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  if (pid < 0) {
    r.stderr_text = std::string("fork failed: ") + std::strerror(errno);
    return r;
  }
  if (pid == 0) {
    // Child: own process group (so a kill reaches its children), limits, redirections.
    ::setpgid(0, 0);
    const auto cpu = static_cast<rlim_t>(std::ceil(limits.cpu_seconds));
    rlimit rl{cpu, cpu + 1};
    ::setrlimit(RLIMIT_CPU, &rl);
    const auto mem = static_cast<rlim_t>(limits.memory_mb * 1024.0 * 1024.0);
    rlimit ml{mem, mem};
    ::setrlimit(RLIMIT_AS, &ml);
    rlimit core{0, 0};
    ::setrlimit(RLIMIT_CORE, &core);
    ::dup2(out_fd, STDOUT_FILENO);
    ::dup2(err_fd, STDERR_FILENO);
    const int devnull = ::open("/dev/null", O_RDONLY);
    if (devnull >= 0) ::dup2(devnull, STDIN_FILENO);
    ::execv(args[0], args.data());
    std::fprintf(stderr, "exec %s failed: %s\n", args[0], std::strerror(errno));
    ::_exit(127);
  }
  r.started = true;
  int status = 0;
  for (;;) {
    const pid_t w = ::waitpid(pid, &status, WNOHANG);
    if (w == pid) break;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (elapsed > limits.wall_seconds && !r.timed_out) {
      r.timed_out = true;
      ::kill(-pid, SIGKILL);
      ::kill(pid, SIGKILL);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  r.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (WIFEXITED(status)) {
    r.exited = true;
    r.exit_code = WEXITSTATUS(status);
  } else if (WIFSIGNALED(status)) {
    r.signal = WTERMSIG(status);
  }
  r.output = slurp_fd(out_fd);
  r.stderr_text = slurp_fd(err_fd);
  ::close(out_fd);
  ::close(err_fd);
  return r;
}

}  // namespace pinsim
