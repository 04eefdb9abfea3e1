// Replays the fuzz targets' seed and regression corpora through the same entry functions
// libFuzzer drives, so an input that once crashed pinsim fails the normal test suite (no
// clang needed). Every input must be accepted or refused with a message that names the file
// and JSON path; the shipped configs must be accepted.
#include <algorithm>
#include <catch2/catch.hpp>
#include <filesystem>
#include <string>
#include <vector>

#include "fuzz_entries.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using pinsim::fuzz::Outcome;

namespace {

const fs::path kFuzzDir = fs::path(PINSIM_TEST_SOURCE_DIR) / "fuzz";
const fs::path kConfigs = fs::path(PINSIM_SOURCE_DIR) / "configs";

/// The files of `dir` (recursively), sorted; none if it does not exist.
std::vector<fs::path> files_in(const fs::path& dir, bool recursive = true) {
  std::vector<fs::path> out;
  if (!fs::is_directory(dir)) return out;
  if (recursive) {
    for (const auto& e : fs::recursive_directory_iterator(dir))
      if (e.is_regular_file()) out.push_back(e.path());
  } else {
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file()) out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

bool is_schema(const fs::path& f) {
  return f.filename().string().find(".schema.") != std::string::npos;
}

/// Runs every file through target `name`; returns how many were accepted.
std::size_t replay(const std::string& name, const std::vector<fs::path>& files) {
  const auto entry = pinsim::fuzz::entry(name);
  REQUIRE(entry != nullptr);
  // Parsing may compute with inf and NaN on purpose (to refuse them); the fuzzer runs
  // without the test main's traps, and so does the replay.
  pinsim::test::FpTrapsOff traps_off;
  std::size_t accepted = 0;
  for (const fs::path& f : files) {
    INFO(name << " input " << f.string());
    const auto r = entry(pinsim::test::read_file(f));
    INFO(r.message);
    // Every refusal names its place (sweep configs once let type errors through as
    // nlohmann's own type_error.302, naming nothing).
    CHECK(r.outcome != Outcome::other);
    accepted += r.outcome == Outcome::accepted;
  }
  return accepted;
}

/// The hand-made seeds and the regressions of target `name`.
std::vector<fs::path> corpus(const std::string& name) {
  auto out = files_in(kFuzzDir / "corpus" / name);
  for (const auto& f : files_in(kFuzzDir / "regressions" / name)) out.push_back(f);
  return out;
}

/// The shipped configs that must be accepted, each checked on its own.
void require_accepted(const std::string& name, const std::vector<fs::path>& files) {
  for (const fs::path& f : files) {
    if (is_schema(f)) continue;
    CAPTURE(f.string());
    CHECK(replay(name, {f}) == 1);
  }
}

}  // namespace

TEST_CASE("fuzz corpus: scenes") {
  std::vector<fs::path> shipped = files_in(kConfigs, false);
  for (const char* sub : {"crosscheck", "grading/scenes"})
    for (const auto& f : files_in(kConfigs / sub)) shipped.push_back(f);
  require_accepted("scene", shipped);
  replay("scene", corpus("scene"));
}

TEST_CASE("fuzz corpus: --set") {
  CHECK(replay("set", {kFuzzDir / "corpus" / "set" / "several"}) == 1);  // the target works
  replay("set", corpus("set"));
}

TEST_CASE("fuzz corpus: sweep configs") {
  std::vector<fs::path> shipped = files_in(kConfigs / "bench");
  for (const auto& f : files_in(kConfigs / "stress")) shipped.push_back(f);
  require_accepted("sweep_config", shipped);
  replay("sweep_config", corpus("sweep_config"));
}

TEST_CASE("fuzz corpus: rubrics") {
  require_accepted("rubric", files_in(kConfigs / "grading", false));
  replay("rubric", corpus("rubric"));
}
