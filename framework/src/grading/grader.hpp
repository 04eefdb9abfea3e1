// The autograder: a rubric of checks run against a submitted plugin or backend, each check
// in its own child process with limits, reported as Gradescope results.json, JUnit XML and
// a readable summary.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "grading/child_process.hpp"

namespace pinsim {

/// One rubric entry.
struct RubricTest {
  std::string name;
  std::string check;   ///< load, gradient, dfdx, ..., reference, simulation, backend_*
  std::string plugin;  ///< the submission's plugin this test is about
  double points = 1.0;
  std::string visibility =
      "visible";        ///< Gradescope: visible, hidden, after_due_date, after_published
  std::string hint;     ///< told to the student when the test fails
  nlohmann::json spec;  ///< the whole entry (check-specific keys)
};

struct Rubric {
  std::filesystem::path file;
  std::string name;
  std::string kind;  ///< "force" or "backend"
  ChildLimits limits;
  ChildLimits build_limits{120.0, 4096.0, 300.0};
  std::vector<RubricTest> tests;
};

/// Reads and validates a rubric; errors name the file and JSON path.
Rubric load_rubric(const std::filesystem::path& file);

struct GradeOptions {
  std::filesystem::path submission;  ///< source folder, folder of libraries, or one library
  std::filesystem::path out;         ///< where results.json etc. go
  std::filesystem::path pinsim_exe;  ///< this program, run as the child worker
  std::filesystem::path sdk_prefix;  ///< where find_package(pinsim) looks (source submissions)
};

struct TestOutcome {
  bool passed = false;
  double score = 0.0;
  std::string output;
  double seconds = 0.0;
};

/// Grades one submission; never throws for anything the submission does. Writes
/// results.json, junit.xml and summary.txt into opt.out and returns results.json's content.
nlohmann::json grade_submission(const Rubric& rubric, const GradeOptions& opt);

/// The body of the child process for test `index` (`pinsim grade-worker`): prints one JSON
/// object {"passed": bool, "output": "..."} to stdout.
int grade_worker(const std::filesystem::path& rubric_file, std::size_t index,
                 const std::filesystem::path& libraries);

/// JUnit XML for a Gradescope results object.
std::string junit_xml(const nlohmann::json& results, const std::string& suite);

}  // namespace pinsim
