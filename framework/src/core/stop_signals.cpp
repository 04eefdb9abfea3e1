#include "core/stop_signals.hpp"

#include <signal.h>

#include <cerrno>

namespace pinsim {

const int kStopSignals[10] = {SIGINT,  SIGTERM, SIGHUP,  SIGQUIT,   SIGPIPE,
                              SIGUSR1, SIGUSR2, SIGALRM, SIGVTALRM, SIGXCPU};

namespace {

std::atomic<int> g_stop{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler stores into it");
std::atomic<SecondStopAction> g_second_action{nullptr};
static_assert(std::atomic<SecondStopAction>::is_always_lock_free, "the signal handler reads it");

/// Records the first stop signal; false if one was recorded before (`first` then holds it).
bool record(int sig, int& first) noexcept {
  first = 0;
  return g_stop.compare_exchange_strong(first, sig);
}

extern "C" void on_stop_signal(int sig) {
  int first = 0;
  if (record(sig, first) || first != sig) return;  // the first, or another kind: noted
  // A closed pipe raises SIGPIPE at every write to it (a log line after `| head` ended):
  // those writes fail with EPIPE instead, and the command stops as after the first.
  if (sig == SIGPIPE) return;
  // A second signal of the same kind: the process ends of it, after the action (a run's
  // summary.json) is done. Raised now, the signal is delivered when this handler returns.
  const int saved_errno = errno;
  if (const SecondStopAction action = g_second_action.load()) action(sig);
  struct sigaction dfl = {};
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  ::sigaction(sig, &dfl, nullptr);
  errno = saved_errno;
  ::raise(sig);
}

}  // namespace

void install_stop_handlers() {
  struct sigaction sa = {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  // SA_RESTART: the signal must not fail a write or read elsewhere; loops poll the flag.
  // A second signal of the same kind gets the default action from the handler itself.
  sa.sa_flags = SA_RESTART;
  for (int s : kStopSignals) {
    // Under nohup (SIGHUP ignored when pinsim started) a hangup stays ignored. SIGINT and
    // SIGQUIT, which a shell ignores for its background jobs, are caught all the same, so
    // that `kill -INT` stops a sweep started with `&` cleanly.
    struct sigaction old = {};
    if (s == SIGHUP && ::sigaction(s, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
    ::sigaction(s, &sa, nullptr);
  }
}

const std::atomic<int>& stop_signal() { return g_stop; }

void request_stop(int sig) noexcept {
  int first = 0;
  record(sig, first);
}

void set_second_stop_action(SecondStopAction action) noexcept { g_second_action.store(action); }

const char* signal_abbrev(int sig) noexcept {
  switch (sig) {
    case SIGHUP:
      return "SIGHUP";
    case SIGINT:
      return "SIGINT";
    case SIGQUIT:
      return "SIGQUIT";
    case SIGILL:
      return "SIGILL";
    case SIGTRAP:
      return "SIGTRAP";
    case SIGABRT:
      return "SIGABRT";
    case SIGBUS:
      return "SIGBUS";
    case SIGFPE:
      return "SIGFPE";
    case SIGKILL:
      return "SIGKILL";
    case SIGSEGV:
      return "SIGSEGV";
    case SIGPIPE:
      return "SIGPIPE";
    case SIGALRM:
      return "SIGALRM";
    case SIGUSR1:
      return "SIGUSR1";
    case SIGUSR2:
      return "SIGUSR2";
    case SIGVTALRM:
      return "SIGVTALRM";
    case SIGTERM:
      return "SIGTERM";
    case SIGXCPU:
      return "SIGXCPU";
    case SIGXFSZ:
      return "SIGXFSZ";
    case SIGSYS:
      return "SIGSYS";
    default:
      return "signal";
  }
}

std::string signal_name(int sig) {
  const std::string s = signal_abbrev(sig);
  return s == "signal" ? "signal " + std::to_string(sig) : s;
}

}  // namespace pinsim
