// Helpers shared by the tests.
#pragma once

#include <fenv.h>
#include <sys/types.h>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace pinsim::test {

/// Turns the test main's floating-point traps off for a scope (for tests that make NaNs
/// on purpose, such as NaN detection).
class FpTrapsOff {
 public:
  FpTrapsOff() : saved_(fegetexcept()) { fedisableexcept(FE_ALL_EXCEPT); }
  ~FpTrapsOff() {
    feclearexcept(FE_ALL_EXCEPT);
    feenableexcept(saved_);
  }
  FpTrapsOff(const FpTrapsOff&) = delete;
  FpTrapsOff& operator=(const FpTrapsOff&) = delete;

 private:
  int saved_;
};

/// Whether this build has AddressSanitizer (the asan preset).
#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kAddressSanitizer = true;
#else
inline constexpr bool kAddressSanitizer = false;
#endif
#else
inline constexpr bool kAddressSanitizer = false;
#endif

/// Shell variable assignments to put before a `pinsim play` window's command under Xvfb.
/// Under ASan: SDL's software renderer and an unaccelerated window framebuffer, so SDL loads
/// no OpenGL. Otherwise SDL loads Mesa's driver (dri/swrast_dri.so) through libGLX_mesa,
/// which unloads it again with 240 bytes still held by the driver's globals; LeakSanitizer
/// then reports them from a module that is gone, which no suppression can name (with the
/// driver kept loaded by LD_PRELOAD, nothing is reported). pinsim's code is the same either
/// way: it asks SDL for a renderer and draws with SDL's calls. Elsewhere: nothing.
inline std::string play_window_env() {
  return kAddressSanitizer ? "SDL_RENDER_DRIVER=software SDL_FRAMEBUFFER_ACCELERATION=0 " : "";
}

/// A fresh empty folder under the build tree's temp area, unique per call.
std::filesystem::path temp_dir(const std::string& tag);

/// Writes text to a file, creating folders.
void write_file(const std::filesystem::path& p, const std::string& text);

/// Reads a whole file.
std::string read_file(const std::filesystem::path& p);

/// A command's exit status (-1 if it did not exit normally) and its stdout and stderr.
struct CommandResult {
  int code;
  std::string output;
};

/// Runs a shell command line, capturing stdout and stderr together.
CommandResult shell(const std::string& command);

/// Runs the pinsim program of this build with these arguments (shell syntax).
CommandResult pinsim_cli(const std::string& args);

/// Starts the pinsim program of this build with `args` (no shell), stdout and stderr into
/// `log`, with SIGINT, SIGTERM, SIGHUP and SIGQUIT at their defaults (a test run in the
/// background may inherit them ignored). Returns its pid.
pid_t spawn_pinsim(const std::vector<std::string>& args, const std::filesystem::path& log);

/// Waits for child `pid`: its exit code, or -N if signal N killed it.
int wait_pinsim(pid_t pid);

/// Polls `ready` every 10 ms until it holds (true) or `seconds` pass (false): for waiting on
/// a progress file instead of sleeping blindly.
bool wait_until(const std::function<bool()>& ready, double seconds = 120.0);

}  // namespace pinsim::test
