#include "tools/child_process.hpp"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <thread>

namespace pinsim {

Child start_child(const std::vector<std::string>& argv, ChildOutput output) {
  int fds[2] = {-1, -1};
  if (output == ChildOutput::Capture && ::pipe(fds) != 0)
    throw std::runtime_error("cannot create a pipe to run " + argv[0]);
  std::fflush(nullptr);  // buffered output would otherwise be written twice
  const pid_t pid = ::fork();
  if (pid < 0) {
    if (fds[0] >= 0) {
      ::close(fds[0]);
      ::close(fds[1]);
    }
    throw std::runtime_error("cannot fork to run " + argv[0]);
  }
  if (pid == 0) {
    if (output == ChildOutput::Capture) {
      ::dup2(fds[1], STDOUT_FILENO);
      ::dup2(fds[1], STDERR_FILENO);
      ::close(fds[0]);
      ::close(fds[1]);
    } else if (output == ChildOutput::Discard) {
      const int devnull = ::open("/dev/null", O_WRONLY);
      if (devnull >= 0) ::dup2(devnull, STDOUT_FILENO);
    }
    std::vector<char*> c;
    for (const auto& a : argv) c.push_back(const_cast<char*>(a.c_str()));
    c.push_back(nullptr);
    ::execvp(c[0], c.data());
    ::_exit(127);
  }
  Child child;
  child.pid = pid;
  if (output == ChildOutput::Capture) {
    ::close(fds[1]);
    child.out = fds[0];
  }
  return child;
}

int wait_child(pid_t pid) {
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

pid_t wait_any_child(const std::atomic<int>* stop) {
  int status = 0;
  for (;;) {
    const pid_t pid = ::waitpid(-1, &status, stop != nullptr ? WNOHANG : 0);
    if (pid > 0 || (pid < 0 && errno != EINTR)) return pid;
    if (stop != nullptr && stop->load() != 0) return 0;
    if (pid == 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

Captured capture(const std::vector<std::string>& argv) {
  const Child child = start_child(argv, ChildOutput::Capture);
  Captured r;
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(child.out, buf, sizeof buf);
    if (n > 0)
      r.output.append(buf, static_cast<std::size_t>(n));
    else if (n == 0 || errno != EINTR)
      break;
  }
  ::close(child.out);
  r.code = wait_child(child.pid);
  return r;
}

}  // namespace pinsim
