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
