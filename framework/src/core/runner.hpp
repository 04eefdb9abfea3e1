// Running a scene to its end: the time loop with output, checks and a summary.
#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>

#include "core/simulation.hpp"

namespace pinsim {

struct RunSettings {
  RunOptions options;
  std::optional<std::filesystem::path> out;  ///< output folder, or none
  bool overwrite = false;                    ///< replace an earlier run's files in `out`
  const std::atomic<bool>* stop = nullptr;   ///< set (e.g. by SIGINT) to end the run cleanly
  /// Called about every 0.2 s of wall time with the fraction done.
  std::function<void(double fraction, const Simulation&)> progress;
};

struct RunResult {
  nlohmann::json summary;  ///< what summary.json holds
  int exit_code = 0;       ///< 0 ok, 1 numeric or plugin failure, 130 interrupted
};

/// Builds the simulation and runs it. Scene, load and plugin-creation errors throw (nothing
/// has run then); failures during the run are caught, recorded in the summary and files,
/// and returned with a non-zero exit code.
RunResult run_scene(const Scene& scene, PluginLoader& loader, const RunSettings& settings);

}  // namespace pinsim
