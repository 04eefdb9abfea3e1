// A submission made ready for its tests: libraries copied, or a source folder configured and
// built in the sandbox (each plugin target on its own: one that does not compile costs only
// its own tests), into a private staging folder the tests' sandboxes see read-only.
#pragma once

#include <filesystem>
#include <string>

#include "grading/rubric.hpp"

namespace pinsim::grading {

struct PreparedSubmission {
  std::filesystem::path staging;    ///< private temporary folder, removed by the destructor
  std::filesystem::path libraries;  ///< staging/lib: the plugin libraries the tests load
  std::string problem;    ///< non-empty: nothing can be graded, and why (shown on every test)
  std::string build_log;  ///< the build's output when some target failed to build
  /// What the copy of the submission left out and why ("" when nothing): shown once.
  std::string copy_notes;
  double seconds = 0.0;  ///< time spent configuring and building
  /// The pinsim program the tests' workers run: the grader's own, or in the fallback
  /// sandbox a copy in the staging folder (the grader's may sit in a folder only it can read).
  std::filesystem::path worker_program;

  PreparedSubmission() = default;
  PreparedSubmission(const PreparedSubmission&) = delete;
  PreparedSubmission& operator=(const PreparedSubmission&) = delete;
  ~PreparedSubmission();
};

/// Copies or builds `submission` (a source folder with a CMakeLists.txt, a folder of
/// libraries, or one library); `sdk_prefix` is where find_package(pinsim) finds the SDK.
void prepare_submission(const std::filesystem::path& submission,
                        const std::filesystem::path& sdk_prefix, const Rubric& rubric,
                        PreparedSubmission& out);

/// Sets `out.worker_program` for this sandbox mode (copying `exe` where the mode needs it).
void stage_worker_program(const std::filesystem::path& exe, PreparedSubmission& out);

}  // namespace pinsim::grading
