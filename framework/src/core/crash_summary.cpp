#include "core/crash_summary.hpp"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <string>

#include "core/output_file.hpp"
#include "core/stop_signals.hpp"

namespace fs = std::filesystem;

namespace pinsim {
namespace {

constexpr int kCrashSignals[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT};
constexpr int kCount = sizeof kCrashSignals / sizeof kCrashSignals[0];

/// Everything the handler touches, prepared in advance.
struct Armed {
  int fd = -1;
  std::string prefix;              // the summary's JSON without its closing "\n}"
  std::string interrupted_prefix;  // the same with the status "interrupted"
  std::string tmp, dest;           // summary.json.crash.PID, summary.json
  struct sigaction old[kCount] = {};
  stack_t old_stack = {};
  bool disarmed = false;
};
Armed* g_armed = nullptr;
std::atomic<uint64_t> g_step{0};
std::atomic<const char*> g_notice{nullptr};  // set_crash_notice's line
static_assert(std::atomic<uint64_t>::is_always_lock_free, "the signal handler reads it");
static_assert(std::atomic<const char*>::is_always_lock_free, "the signal handler reads it");

// A stack for the handler: a stack overflow leaves none on the thread's own.
alignas(16) char g_alt_stack[1 << 16];

/// Appends `v` in decimal at `p`; returns the new end. Async-signal-safe.
char* put_uint(char* p, uint64_t v) {
  char digits[24];
  int n = 0;
  do {
    digits[n++] = static_cast<char>('0' + v % 10);
    v /= 10;
  } while (v != 0);
  while (n > 0) *p++ = digits[--n];
  return p;
}

char* put_str(char* p, const char* s) {
  const std::size_t n = std::strlen(s);
  std::memcpy(p, s, n);
  return p + n;
}

/// Writes the summary of a process that a signal is ending: `prefix` (its status), then the
/// steps, the signal and the error of `kind` ("... by SIGSEGV during step N"), and renames it
/// over summary.json. Async-signal-safe; once per process.
void write_last_summary(Armed* a, int sig, const std::string& prefix, const char* kind,
                        const char* message) {
  if (a == nullptr || a->fd < 0) return;
  const uint64_t steps = g_step.load(std::memory_order_relaxed);
  const char* name = signal_abbrev(sig);
  char tail[512];
  char* p = tail;
  p = put_str(p, ",\n  \"steps\": ");
  p = put_uint(p, steps);
  p = put_str(p, ",\n  \"signal\": {\n    \"name\": \"");
  p = put_str(p, name);
  p = put_str(p, "\",\n    \"number\": ");
  p = put_uint(p, static_cast<uint64_t>(sig));
  p = put_str(p, "\n  },\n  \"error\": {\n    \"kind\": \"");
  p = put_str(p, kind);
  p = put_str(p, "\",\n    \"message\": \"");
  p = put_str(p, message);
  p = put_str(p, name);
  p = put_str(p, " during step ");
  p = put_uint(p, steps + 1);
  p = put_str(p, "\",\n    \"step\": ");
  p = put_uint(p, steps + 1);
  p = put_str(p, "\n  }\n}\n");
  if (write_all(a->fd, prefix.data(), prefix.size()) == 0 &&
      write_all(a->fd, tail, static_cast<std::size_t>(p - tail)) == 0 && ::close(a->fd) == 0)
    ::rename(a->tmp.c_str(), a->dest.c_str());
  a->fd = -1;
}

extern "C" void on_crash(int sig) {
  const int saved_errno = errno;
  Armed* a = g_armed;
  if (a != nullptr) write_last_summary(a, sig, a->prefix, "crash", "the process was killed by ");
  // The previous action (the default, or a test framework's) gets the signal next: raised
  // now, it is delivered when this handler returns.
  for (int i = 0; i < kCount; ++i)
    if (kCrashSignals[i] == sig && a != nullptr) ::sigaction(sig, &a->old[i], nullptr);
  errno = saved_errno;
  ::raise(sig);
}

extern "C" void on_crash_notice(int sig) {
  if (const char* line = g_notice.load(std::memory_order_relaxed)) {
    char head[64];
    char* p = put_str(head, "pinsim: killed by ");
    p = put_str(p, signal_abbrev(sig));
    p = put_str(p, " ");
    (void)write_all(STDERR_FILENO, head, static_cast<std::size_t>(p - head));
    (void)write_all(STDERR_FILENO, line, std::strlen(line));
    (void)write_all(STDERR_FILENO, "\n", 1);
  }
  struct sigaction dfl = {};
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  ::sigaction(sig, &dfl, nullptr);
  ::raise(sig);  // delivered with the default action when this handler returns
}

/// A second SIGINT (SIGTERM, ...) while the run finishes its step: stop_signals ends the
/// process with it after this.
void on_second_stop(int sig) {
  Armed* a = g_armed;
  if (a != nullptr && !a->disarmed)
    write_last_summary(a, sig, a->interrupted_prefix, "signal",
                       "the process was ended by a second ");
}

}  // namespace

CrashSummary::CrashSummary(const fs::path& dir, nlohmann::json summary) {
  auto a = new Armed;
  summary["status"] = "crashed";
  summary.erase("steps");
  summary.erase("signal");
  summary.erase("error");
  a->prefix = summary.dump(2);
  // dump(2) of an object ends with "\n}"; the handler appends its keys and the brace.
  a->prefix.resize(a->prefix.size() - 2);
  summary["status"] = "interrupted";
  a->interrupted_prefix = summary.dump(2);
  a->interrupted_prefix.resize(a->interrupted_prefix.size() - 2);
  a->dest = (dir / "summary.json").string();
  a->tmp = a->dest + ".crash." + std::to_string(::getpid());
  g_notice.store(nullptr, std::memory_order_relaxed);  // summary.json will say it
  a->fd = ::open(a->tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (a->fd < 0) {
    const std::string msg = output_error_text(a->tmp, "write", errno);
    delete a;
    throw OutputError(msg);
  }
  // Blocks for the summary, taken now while there is space; the file's size stays 0. Where
  // the file system cannot reserve, the crash summary is still written if there is room.
  (void)::fallocate(a->fd, FALLOC_FL_KEEP_SIZE, 0, kReserve);
  g_step.store(0, std::memory_order_relaxed);

  stack_t ss = {};
  ss.ss_sp = g_alt_stack;
  ss.ss_size = sizeof g_alt_stack;
  ::sigaltstack(&ss, &a->old_stack);
  struct sigaction sa = {};
  sa.sa_handler = on_crash;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_ONSTACK;
  g_armed = a;
  for (int i = 0; i < kCount; ++i) ::sigaction(kCrashSignals[i], &sa, &a->old[i]);
  set_second_stop_action(on_second_stop);
}

void CrashSummary::disarm() noexcept {
  Armed* a = g_armed;
  if (a == nullptr || a->disarmed) return;
  set_second_stop_action(nullptr);
  for (int i = 0; i < kCount; ++i) ::sigaction(kCrashSignals[i], &a->old[i], nullptr);
  if (a->old_stack.ss_sp != nullptr) ::sigaltstack(&a->old_stack, nullptr);
  a->disarmed = true;
}

int CrashSummary::write_instead(std::string_view bytes) noexcept {
  disarm();
  Armed* a = g_armed;
  if (a == nullptr || a->fd < 0) return EBADF;
  int err = write_all(a->fd, bytes.data(), bytes.size());
  if (::close(a->fd) != 0 && err == 0) err = errno;
  a->fd = -1;
  if (err == 0 && ::rename(a->tmp.c_str(), a->dest.c_str()) != 0) err = errno;
  return err;
}

CrashSummary::~CrashSummary() {
  disarm();
  Armed* a = g_armed;
  if (a == nullptr) return;
  g_armed = nullptr;
  if (a->fd >= 0) ::close(a->fd);
  ::unlink(a->tmp.c_str());
  delete a;
}

void CrashSummary::set_step(uint64_t step) noexcept {
  g_step.store(step, std::memory_order_relaxed);
}

void set_crash_notice(const char* line) noexcept {
  g_notice.store(line, std::memory_order_relaxed);
  static const bool installed = [] {
    stack_t ss = {};
    ss.ss_sp = g_alt_stack;
    ss.ss_size = sizeof g_alt_stack;
    ::sigaltstack(&ss, nullptr);
    struct sigaction sa = {};
    sa.sa_handler = on_crash_notice;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_ONSTACK;
    for (const int sig : kCrashSignals) ::sigaction(sig, &sa, nullptr);
    return true;
  }();
  (void)installed;
}

}  // namespace pinsim
