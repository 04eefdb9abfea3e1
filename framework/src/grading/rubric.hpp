// A grading rubric (configs/grading/*.json, schema configs/grading/rubric.schema.json): the
// checks, their points and visibility, and the limits of the untrusted steps.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "grading/sandbox.hpp"

namespace pinsim {

/// One rubric entry.
struct RubricTest {
  std::string name;
  std::string check;   ///< load, gradient, dfdx, ..., reference, simulation, backend_*
  std::string plugin;  ///< the submission's plugin this test is about
  double points = 1.0;
  /// Gradescope: visible, hidden, after_due_date, after_published (default: the rubric's)
  std::string visibility = "visible";
  std::string hint;     ///< told to the student when the test fails
  nlohmann::json spec;  ///< the whole entry (check-specific keys)
};

struct Rubric {
  std::filesystem::path file;
  std::string name;
  std::string kind;  ///< "force" or "backend"
  /// Gradescope's top-level visibility of the results (and the tests' default), and of the
  /// grader's stdout: visible, hidden, after_due_date, after_published.
  std::string visibility = "visible";
  std::string stdout_visibility = "hidden";
  /// Limits of each test's worker (the wall-clock limit is per test).
  grading::SandboxLimits limits{20.0, 2048.0, 60.0, 64, 64.0, 256, 256.0};
  /// Limits of configuring and of building a source submission (each step).
  grading::SandboxLimits build_limits{120.0, 4096.0, 300.0, 256, 256.0, 1024, 1024.0};
  /// The whole submission's wall-clock budget, s: tests not started by then fail.
  double time_budget_seconds = 600.0;
  /// What a test shows of the submission's printing, KiB (head; the rest is counted).
  double output_limit_kb = 64.0;
  std::vector<RubricTest> tests;
};

/// Reads and validates a rubric; errors (InputError) name the file and JSON path.
Rubric load_rubric(const std::filesystem::path& file);

}  // namespace pinsim
