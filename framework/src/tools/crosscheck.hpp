// Cross-check: the same scene on two collision backends, aligned by time; per particle the
// position deviation, the agreement horizon and the contact sequences side by side, and
// the energy of each run.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/simulation.hpp"

namespace pinsim {

/// The scene's top-level "crosscheck" object (all keys optional):
/// {"backends": ["sdf", "box2d"],
///  "position_tolerance": 1e-3,         // scene length: deviation allowed at every sample
///  "time_of_impact_tolerance": 1e-3,   // s: |t_a - t_b| of matched contacts
///  "normal_tolerance": 1e-2,           // rad: angle between matched contact normals
///  "velocity_tolerance": 1e-2,         // length/s: |vn_after_a - vn_after_b|
///  "min_horizon": 1.0,                 // s: required agreement horizon (default: the run)
///  "params": {"box2d": {...}}}         // backend parameters per backend name
struct CrosscheckSpec {
  std::vector<std::string> backends = {"sdf", "box2d"};
  double position_tolerance = 1e-3;
  double time_of_impact_tolerance = 1e-3;
  double normal_tolerance = 1e-2;
  double velocity_tolerance = 1e-2;
  std::optional<double> min_horizon;
  std::map<std::string, nlohmann::json> params;
};

/// Reads scene.doc["crosscheck"]; throws InputError with the JSON path on bad values.
CrosscheckSpec parse_crosscheck(const Scene& scene);

/// One backend's run, sampled every step.
struct CrosscheckRun {
  std::string backend;
  std::vector<double> t;             ///< sample times, s (t[0] = 0)
  std::vector<Eigen::Matrix2Xd> x;   ///< positions at each sample
  std::vector<double> energy;        ///< kinetic + potential at each sample
  std::vector<pinsim_event> events;  ///< all contact events
  std::string error;                 ///< non-empty if the run stopped early
  double wall_time = 0.0;            ///< s
  int stopped_by = 0;                ///< a stop signal ended the run after `steps` steps
  uint64_t steps = 0;                ///< steps done
};

/// Runs the scene on `backend` (params from spec.params, else the scene's if it names
/// that backend, else defaults). Scene and plugin creation errors throw. A stop signal
/// (stop_signals.hpp) ends the run after the current step (`stopped_by`). With `run_dir`,
/// also writes the run folder `pinsim run --out` writes (trajectory.csv every
/// output.every steps, events.csv, contacts.csv, scene.json with this backend, and a
/// summary.json with status, backend, steps and energy), replacing an earlier one there;
/// `pinsim render` of the folder holding the runs overlays them. Throws OutputError.
CrosscheckRun run_for_crosscheck(const Scene& scene, PluginLoader& loader,
                                 const std::string& backend, const CrosscheckSpec& spec,
                                 const std::filesystem::path* run_dir = nullptr);

struct CrosscheckReport {
  nlohmann::json json;  ///< the full report (report.json)
  std::string table;    ///< a readable summary
  bool pass = false;    ///< every tolerance held
};

/// Compares two runs of `scene` under the tolerances of `spec`.
CrosscheckReport compare_runs(const Scene& scene, const CrosscheckSpec& spec,
                              const CrosscheckRun& a, const CrosscheckRun& b);

}  // namespace pinsim
