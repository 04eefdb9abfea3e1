// The autograder (trusted): prepares a submission (copy or sandboxed build), runs each rubric
// test with the submission's plugin in a sandboxed worker that returns raw numbers, computes
// every verdict itself, and writes Gradescope results.json, JUnit XML and summary.txt
// (atomically, also while grading, so a stopped grader still leaves valid files).
#pragma once

#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>

#include "core/path_comparison.hpp"
#include "grading/rubric.hpp"

namespace pinsim {

struct GradeOptions {
  std::filesystem::path submission;  ///< source folder, folder of libraries, or one library
  std::filesystem::path out;         ///< where results.json etc. go
  std::filesystem::path pinsim_exe;  ///< this program, run as the sandboxed worker
  std::filesystem::path sdk_prefix;  ///< where find_package(pinsim) looks (source submissions)
  /// Draws the picture of a failed simulation or path test (the program passes pictures'
  /// comparison_png: grading does not link cairo). Empty: those tests show text only.
  std::function<ComparisonPicture(const PathComparison&)> draw_comparison;
};

/// The outcome of grading one submission.
struct GradeReport {
  nlohmann::json results;  ///< what results.json holds
  /// The grader could not grade (no sandbox here, an internal error): results.json says why
  /// with score 0, and `pinsim grade` exits 2.
  bool refused = false;
  /// A stop signal (SIGINT, SIGTERM, SIGHUP, SIGQUIT) ended grading after the current test:
  /// results.json lists the tests done, score 0, and says so. `pinsim grade` exits 128 + it.
  int stopped_by = 0;
  /// Why results.json could not be written ("" when it was): `pinsim grade` then exits 2.
  std::string write_error;
};

/// Grades one submission. Never throws and never fails because of what the submission does;
/// results.json, junit.xml and summary.txt are always written (score 0 and the reason when
/// the grader itself fails).
GradeReport grade_submission(const Rubric& rubric, const GradeOptions& opt);

/// The body of `pinsim grade-worker` (inside the sandbox): serves the grader's channel.
int grade_worker(const std::filesystem::path& libraries);

}  // namespace pinsim
