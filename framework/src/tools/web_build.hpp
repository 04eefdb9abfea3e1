// Compiling plugin folders for `pinsim share`'s page. Each folder is built as its author
// builds it natively (a CMakeLists.txt with find_package(pinsim) and pinsim_add_plugin, as
// sdk/pinball_starter), but configured with Emscripten against the web SDK; the SDK links
// the prebuilt engine and every plugin of the folders into one pinsim_web.js. Neither
// pinsim's source tree nor a rebuild of the engine is needed.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace pinsim {

/// A linked page engine.
struct WebBuild {
  std::filesystem::path module;   ///< pinsim_web.js (the wasm embedded)
  std::filesystem::path plugins;  ///< pinsim_web.plugins: the names linked in, one a line
  double seconds = 0.0;           ///< wall time of the configure and the build
};

/// Builds `sources` (plugin folders) against the web SDK `sdk` (the folder that holds
/// cmake/pinsimConfig.cmake) in `build_dir` (created; its build.log keeps the tools'
/// output). InputError for a folder that is not a plugin folder; std::runtime_error naming
/// the folders, with the end of the log, when Emscripten, CMake or the compiler fails.
WebBuild build_web_engine(const std::vector<std::filesystem::path>& sources,
                          const std::filesystem::path& sdk, const std::filesystem::path& build_dir,
                          int jobs);

}  // namespace pinsim
