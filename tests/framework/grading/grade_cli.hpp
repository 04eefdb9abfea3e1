// `pinsim -q grade` as a student's run of it, for the grading tests: the results.json it
// wrote (required to exist), the exit code and what it printed.
#pragma once

#include <catch2/catch.hpp>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "test_support.hpp"

namespace pinsim::test {

struct Graded {
  std::filesystem::path file;  ///< results.json
  nlohmann::json results;
  int code = -1;
  std::string printed;
};

/// Grades `submission` with `rubric` into a fresh temporary folder named after `tag`.
inline Graded grade(const std::filesystem::path& rubric, const std::filesystem::path& submission,
                    const std::string& tag) {
  const std::filesystem::path out = temp_dir("grade-" + tag);
  const auto r = pinsim_cli("-q grade --rubric " + rubric.string() + " --submission " +
                            submission.string() + " --out " + out.string() + " 2>&1");
  INFO(r.output.substr(0, 4000));
  REQUIRE(std::filesystem::exists(out / "results.json"));
  return {out / "results.json", nlohmann::json::parse(read_file(out / "results.json")), r.code,
          r.output};
}

}  // namespace pinsim::test
