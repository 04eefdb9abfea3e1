// Hostile "linear_spring" submissions for the grader's sandbox tests, one per -DHOSTILE value.
// Each is the correct student spring (correct_source/student_spring.hpp) plus one attack a
// real student could write: forged verdicts, escaping children, snooping, writing outside,
// the network, a fork bomb, floods of output, invalid text, loading the reference, a hang.
// The grader's tests (test_grading_hostile.cpp) assert the exact outcome of each.
#include <arpa/inet.h>
#include <dlfcn.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "correct_source/student_spring.hpp"

namespace {

// Attacks that act when the library is loaded, before any plugin call.
[[maybe_unused]] __attribute__((constructor)) void on_load() {
#if HOSTILE == 1 || HOSTILE == 2
  // The old grader read its verdict from the worker's output: print one, then quit.
  std::FILE* out = HOSTILE == 1 ? stdout : stderr;
  std::fprintf(out, "{\"passed\": true, \"output\": \"forged\"}\n");
  for (int i = 0; i < 40; ++i) std::fprintf(out, "{\"passed\": true, \"score\": 100}\n");
  std::fflush(out);
  ::_exit(0);
#elif HOSTILE == 3
  // Write a forged reply on every descriptor that might be the grader's channel.
  const char forged[] = "{\"passed\": true, \"output\": \"forged\"}\n";
  for (int fd = 3; fd < 16; ++fd) [[maybe_unused]] auto w = ::write(fd, forged, sizeof forged);
#endif
}

std::string try_read(const char* path) {
  const int fd = ::open(path, O_RDONLY);
  if (fd < 0) return std::string("cannot read ") + path + ": " + std::strerror(errno);
  char buf[64] = {};
  const ssize_t n = ::read(fd, buf, sizeof buf - 1);
  ::close(fd);
  return std::string("READ ") + path + ": " + (n > 0 ? std::string(buf, n) : "");
}

std::string try_write(const char* path) {
  const int fd = ::open(path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) return std::string("cannot write ") + path + ": " + std::strerror(errno);
  [[maybe_unused]] auto w = ::write(fd, "escaped\n", 8);
  ::close(fd);
  return std::string("WROTE ") + path;
}

class Hostile : public StudentSpring {
 public:
  explicit Hostile(const pinsim::CreateContext& c) : StudentSpring(c) {
#if HOSTILE == 4
    // A grandchild in its own session that outlives the test and keeps trying to rewrite
    // the grader's results.
    static bool once = false;
    if (!once) {
      once = true;
      if (::fork() == 0) {
        ::setsid();
        if (::fork() == 0) {
          ::execl("/bin/sh", "sh", "-c",
                  "for i in $(seq 200); do echo forged > " HOSTILE_RESULTS
                  " 2>/dev/null; echo forged > /tmp/pinsim-hostile-escape-wrote; sleep 0.1; done",
                  "pinsim-hostile-escape-marker", static_cast<char*>(nullptr));
        }
        ::_exit(0);
      }
    }
#elif HOSTILE == 5
    for (const char* p : {"/etc/passwd", "/etc/shadow", HOSTILE_RUBRIC, HOSTILE_SCENE,
                          HOSTILE_OTHER_SUBMISSION, "/proc/1/environ"})
      std::printf("%s\n", try_read(p).c_str());
#elif HOSTILE == 6
    for (const char* p :
         {"/tmp/pinsim-hostile-write-marker", HOSTILE_SOURCE_MARKER,
          "/submission/lib/pinsim-hostile-write-marker", "/grader/pinsim-hostile-write-marker"})
      std::printf("%s\n", try_write(p).c_str());
#elif HOSTILE == 7
    const int s = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(HOSTILE_PORT);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0)
      std::printf("CONNECTED to 127.0.0.1:%d\n", HOSTILE_PORT);
    else
      std::printf("connect to 127.0.0.1:%d failed: %s\n", HOSTILE_PORT, std::strerror(errno));
    ::close(s);
#elif HOSTILE == 8
    for (;;) {
      if (::fork() == 0) ::prctl(PR_SET_NAME, "hostilebomb", 0, 0, 0);
    }
#elif HOSTILE == 9
    static bool once = false;
    if (!once) {
      once = true;
      static char line[1 << 20];
      std::memset(line, 'x', sizeof line);
      line[sizeof line - 1] = '\n';
      for (int i = 0; i < 1024; ++i) std::fwrite(line, 1, sizeof line, stdout);  // 1 GiB
      std::fflush(stdout);
    }
#elif HOSTILE == 10
    std::printf("debug: k = 10 \x1b[31mred\x1b[0m \xff\xfe bad \xe2\x82 cut \x01\x02\x7f");
    std::printf(" </failure>]]><![CDATA[ & \"quoted\" \xc0\xaf overlong\n");
    std::fflush(stdout);
    std::fwrite("nul\0byte\n", 1, 9, stderr);
#elif HOSTILE == 11
    // Forward to the shipped reference if it can be loaded (it must not be).
    for (const char* p : {HOSTILE_REFERENCE, "libpinsim_plugin_linear_spring.so",
                          "/usr/local/lib/pinsim/plugins/libpinsim_plugin_linear_spring.so"}) {
      reference_ = ::dlopen(p, RTLD_NOW | RTLD_LOCAL);
      std::printf("dlopen %s: %s\n", p, reference_ ? "LOADED" : ::dlerror());
      if (reference_) break;
    }
#elif HOSTILE == 12
    for (;;) ::pause();
#endif
  }
#if HOSTILE == 11
  // Without the reference, no force at all: consistent (f = -grad E with E = 0) but wrong.
  void add_force(const pinsim::StateView& s, pinsim::ForceOut& f) const {
    if (reference_) StudentSpring::add_force(s, f);
  }
  double energy(const pinsim::StateView& s) const {
    return reference_ ? StudentSpring::energy(s) : 0.0;
  }
  void add_dfdx(const pinsim::StateView& s, pinsim::Triplets& j) const {
    if (reference_) StudentSpring::add_dfdx(s, j);
  }

 private:
  void* reference_ = nullptr;
#endif
};

}  // namespace

PINSIM_PLUGIN(Hostile)
