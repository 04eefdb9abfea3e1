#define CATCH_CONFIG_RUNNER
#include <fenv.h>

#include <catch2/catch.hpp>

int main(int argc, char** argv) {
  feenableexcept(FE_INVALID | FE_DIVBYZERO);
  return Catch::Session().run(argc, argv);
}

#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "test_support.hpp"

namespace pinsim::test {

std::filesystem::path temp_dir(const std::string& tag) {
  static std::atomic<int> counter{0};
  auto d = std::filesystem::temp_directory_path() / ("pinsim-test-" + std::to_string(::getpid()) +
                                                     "-" + tag + "-" + std::to_string(counter++));
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

void write_file(const std::filesystem::path& p, const std::string& text) {
  if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path());
  std::ofstream(p) << text;
}

std::string read_file(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

CommandResult shell(const std::string& command) {
  CommandResult r{-1, {}};
  std::FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (p == nullptr) throw std::runtime_error("popen failed: " + command);
  char buf[4096];
  while (std::size_t n = std::fread(buf, 1, sizeof buf, p)) r.output.append(buf, n);
  const int status = ::pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

CommandResult pinsim_cli(const std::string& args) {
  return shell(std::string(PINSIM_BIN) + " " + args);
}

}  // namespace pinsim::test
