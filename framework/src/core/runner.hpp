// Running a scene to its end: the time loop with output, checks and a summary.
#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>

#include "core/simulation.hpp"

namespace pinsim {

/// A run whose total energy ends above its start by more than this fraction of the start's
/// kinetic plus |potential| energy, with nothing that adds energy (every force reports its
/// energy; no moving or kicking obstacle, scripted input or restitution above 1), warns:
/// summary.json "warnings" [{"kind": "energy_rise", "message"}]. Symplectic Euler's energy
/// error stays within about omega dt / 2 of the start, far below it for the scenes' steps.
inline constexpr double kEnergyRiseBound = 0.05;

struct RunSettings {
  RunOptions options;
  std::optional<std::filesystem::path> out;  ///< output folder, or none
  bool overwrite = false;                    ///< replace an earlier run's files in `out`
  /// Set to a signal's number (stop_signal(), set by SIGINT, SIGTERM, SIGHUP, SIGQUIT) to end
  /// the run cleanly after the current step.
  const std::atomic<int>* stop = nullptr;
  /// Called about every 0.2 s of wall time with the fraction done.
  std::function<void(double fraction, const Simulation&)> progress;
};

struct RunResult {
  nlohmann::json summary;  ///< what summary.json holds
  /// 0 ok; 1 a numeric, plugin or output failure; 128 + the signal when stopped by one.
  int exit_code = 0;
};

/// Builds the simulation and runs it. Scene, load and plugin-creation errors throw (nothing
/// has run then), as does an output folder that cannot be written at the start
/// (OutputError); failures during the run, a write that fails included, are caught,
/// recorded in the summary and files, and returned with a non-zero exit code. With an output
/// folder, a crash of the process (a plugin's segfault) leaves summary.json saying so
/// (CrashSummary).
RunResult run_scene(const Scene& scene, PluginLoader& loader, const RunSettings& settings);

}  // namespace pinsim
