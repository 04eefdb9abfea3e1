// The verdicts of the rubric's checks, computed in the grader (trusted) on a plugin table
// that may forward to the sandboxed submission (remote_plugin.hpp): check-plugin's checks,
// agreement with a reference plugin on random states, whole simulations against the
// reference, and the collision backend checks.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "core/path_comparison.hpp"
#include "core/plugin_loader.hpp"
#include "grading/rubric.hpp"

namespace pinsim::grading {

struct Verdict {
  bool passed = false;
  std::string output;
  /// False when the test could not run at all (no build, no plugin, no time left): its
  /// output is the cause, and the rubric's physics hint is not added.
  bool ran = true;
  /// For a failed simulation or path test: both paths, where they part and where a ball
  /// went into an obstacle, for the picture beside the output.
  std::optional<PathComparison> figure = std::nullopt;
};

/// Runs test `t` on the submission's plugin `sub`; the rubric's folder resolves scenes.
/// Throws only for the grader's own errors; the submission's misbehaviour is a verdict.
Verdict run_check(const RubricTest& t, const std::shared_ptr<const LoadedPlugin>& sub,
                  const std::filesystem::path& rubric_dir);

}  // namespace pinsim::grading
