// The physics check any plugin author runs on a force plugin (`pinsim check-plugin`):
// random states and element lists, finite-difference gradients and Jacobians, conservation
// laws, rigid-motion invariance, degenerate states and dissipation.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/plugin_loader.hpp"
#include "core/scene.hpp"

namespace pinsim {

/// What to check and how hard.
struct CheckOptions {
  /// Parameters for the instances, as in a scene's "params" (defaults filled in).
  nlohmann::json params = nlohmann::json::object();
  uint64_t seed = 20221025;  ///< random seed: the same seed checks the same states
  int trials = 6;            ///< random states per check
  /// Run the internal-force checks (momentum, angular momentum, rigid invariance) even if
  /// the plugin does not declare PINSIM_CAP_INTERNAL (e.g. gravity in pairwise mode).
  bool assume_internal = false;
  /// Relative error accepted by the finite-difference checks at the smaller step.
  double fd_tolerance = 1e-6;
  /// Relative error accepted by the exact identities (Σf = 0, invariance, dissipation).
  double identity_tolerance = 1e-9;
  /// Run only this check (after "create"); empty: all of them.
  std::string only;
  /// Element topology of the random states (check_layout.hpp): "chain", "ring", "grid",
  /// "body"; empty: chain for a fixed arity, ring for whole-body (arity 0) plugins.
  std::string topology;
  /// Check on this scene's force `force_index` instead: its elements, its parameters
  /// (`params` override them) and states perturbed around its initial state.
  const Scene* scene = nullptr;
  std::size_t force_index = 0;
};

enum class CheckStatus { Pass, Fail, Skip };

/// One check's outcome: its worst error over all states tried, and where that was.
struct CheckResult {
  std::string name;  ///< gradient, dfdx, dfdv, momentum, angular_momentum, ...
  std::string what;  ///< one line: what the check verifies
  CheckStatus status = CheckStatus::Pass;
  double worst = 0.0;      ///< worst (relative) error found
  double tolerance = 0.0;  ///< what was accepted
  std::string detail;      ///< where the worst error was, or why the check was skipped
};

struct CheckReport {
  std::string plugin;  ///< plugin name
  std::string path;    ///< library file
  std::string layout;  ///< the states and elements checked, e.g. "topology ring: ..."
  std::vector<CheckResult> checks;
  /// True when no check failed (skipped checks do not fail).
  bool passed() const;
  /// The check called `name`, or nullptr.
  const CheckResult* find(const std::string& name) const;
};

/// Runs every check on a loaded force plugin. Never throws for plugin misbehaviour (errors,
/// NaNs, wrong shapes become failed checks); throws LoadError if it is not a force plugin
/// and InputError for bad `opt.params`. Floating-point traps are off while it runs.
CheckReport check_force_plugin(const LoadedPlugin& plugin, const CheckOptions& opt = {});

/// A readable pass/fail table, one line per check with its worst error.
std::string format_report(const CheckReport& report);

/// The report as JSON: {"plugin", "path", "passed", "checks": [{name, status, worst, ...}]}.
nlohmann::json report_json(const CheckReport& report);

}  // namespace pinsim
