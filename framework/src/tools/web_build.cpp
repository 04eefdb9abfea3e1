#include "tools/web_build.hpp"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <fstream>

#include "core/input_error.hpp"
#include "tools/child_process.hpp"

namespace pinsim {
namespace {
namespace fs = std::filesystem;

/// The end of a log: its last `lines` lines.
std::string tail(const std::string& text, int lines) {
  std::size_t at = text.size();
  while (at > 0 && lines >= 0) {
    at = text.rfind('\n', at - 1);
    if (at == std::string::npos) return text;
    --lines;
  }
  return text.substr(at + 1);
}

/// Runs argv with stdout and stderr appended to `log`; throws, with the end of the log, if
/// it does not exit 0.
void run_step(const std::vector<std::string>& argv, const std::string& what, std::string& log) {
  log += "$";
  for (const auto& a : argv) log += " " + a;
  log += "\n";
  const Captured c = capture(argv);
  log += c.output;
  if (c.code == 0) return;
  const std::string why =
      c.code == 127 ? argv[0] + " could not be run" : "exit code " + std::to_string(c.code);
  throw std::runtime_error(what + " failed (" + why + "); the end of its output:\n" +
                           tail(log, 40));
}

/// `path` as a CMake bracket argument.
std::string cmake_path(const fs::path& path) {
  const std::string s = path.string();
  if (s.find("]==]") != std::string::npos)
    throw InputError(s + ": a folder name containing \"]==]\" cannot be given to CMake");
  return "[==[" + s + "]==]";
}
}  // namespace

WebBuild build_web_engine(const std::vector<fs::path>& sources, const fs::path& sdk,
                          const fs::path& build_dir, int jobs) {
  std::error_code ec;
  if (!fs::is_regular_file(sdk / "cmake" / "pinsimConfig.cmake", ec))
    throw std::runtime_error("the web SDK " + sdk.string() + " has no cmake/pinsimConfig.cmake");
  std::string names;
  for (const auto& s : sources) {
    if (!fs::is_directory(s, ec)) throw InputError("--source " + s.string() + ": no such folder");
    if (!fs::is_regular_file(s / "CMakeLists.txt", ec))
      throw InputError("--source " + s.string() +
                       ": no CMakeLists.txt (a plugin folder builds its plugins with "
                       "find_package(pinsim) and pinsim_add_plugin, as sdk/pinball_starter)");
    names += (names.empty() ? "" : ", ") + s.string();
  }

  // One project that adds every folder, then links the engine with all their plugins.
  const fs::path project = build_dir / "project";
  fs::create_directories(project);
  {
    std::ofstream out(project / "CMakeLists.txt", std::ios::trunc);
    out << "# Written by pinsim share --source: the plugin folders compiled for the web page.\n"
           "cmake_minimum_required(VERSION 3.20)\n"
           "project(pinsim_share LANGUAGES CXX)\n"
           "find_package(pinsim REQUIRED)\n";
    for (std::size_t k = 0; k < sources.size(); ++k)
      out << "add_subdirectory(" << cmake_path(fs::absolute(sources[k])) << " plugins_" << k
          << ")\n";
    out << "pinsim_web_link_engine()\n";
    if (!out.flush())
      throw std::runtime_error((project / "CMakeLists.txt").string() + ": cannot write");
  }
  // Emscripten's tools find Debian's acorn only with Debian's node modules on NODE_PATH.
  if (const char* np = std::getenv("NODE_PATH"); np == nullptr || *np == '\0')
    ::setenv("NODE_PATH", "/usr/share/nodejs", 1);

  const fs::path out = build_dir / "build";
  std::string log;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    run_step({"emcmake", "cmake", "-S", project.string(), "-B", out.string(),
              "-Dpinsim_DIR=" + (sdk / "cmake").string(), "-DCMAKE_BUILD_TYPE=Release"},
             "configuring " + names + " with Emscripten (emcmake cmake; Debian package emscripten)",
             log);
    run_step({"cmake", "--build", out.string(), "-j", std::to_string(std::max(1, jobs))},
             "compiling " + names + " for the web", log);
  } catch (...) {
    std::ofstream(build_dir / "build.log", std::ios::trunc) << log;
    throw;
  }
  std::ofstream(build_dir / "build.log", std::ios::trunc) << log;
  WebBuild b;
  b.module = out / "pinsim_web.js";
  b.plugins = out / "pinsim_web.plugins";
  b.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!fs::is_regular_file(b.module, ec) || !fs::is_regular_file(b.plugins, ec))
    throw std::runtime_error("compiling " + names + " for the web made no " + b.module.string());
  return b;
}

}  // namespace pinsim
