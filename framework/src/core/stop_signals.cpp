#include "core/stop_signals.hpp"

#include <signal.h>

namespace pinsim {
namespace {

std::atomic<int> g_stop{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler stores into it");

extern "C" void on_stop_signal(int sig) {
  int none = 0;
  g_stop.compare_exchange_strong(none, sig);
}

}  // namespace

void install_stop_handlers() {
  struct sigaction sa = {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  // SA_RESTART: the signal must not fail a write or read elsewhere; loops poll the flag.
  // SA_RESETHAND: a second signal of the same kind gets the default action.
  sa.sa_flags = SA_RESTART | SA_RESETHAND;
  for (int s : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) {
    // Under nohup (SIGHUP ignored when pinsim started) a hangup stays ignored. SIGINT and
    // SIGQUIT, which a shell ignores for its background jobs, are caught all the same, so
    // that `kill -INT` stops a sweep started with `&` cleanly.
    struct sigaction old = {};
    if (s == SIGHUP && ::sigaction(s, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
    ::sigaction(s, &sa, nullptr);
  }
}

const std::atomic<int>& stop_signal() { return g_stop; }

void request_stop(int sig) noexcept { on_stop_signal(sig); }

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
