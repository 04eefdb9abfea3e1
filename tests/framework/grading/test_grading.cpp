// The autograder on fixture submissions: each finishes with its expected score and message,
// whatever it does (wrong physics, crash, hang, huge allocation, wrong ABI, no build).
#include <sys/wait.h>

#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <utility>
#include <vector>

#include "test_support.hpp"

using Catch::Matchers::Contains;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const fs::path subs = PINSIM_GRADING_SUBMISSIONS;
const fs::path src = PINSIM_GRADING_SOURCE;
const fs::path configs = PINSIM_SOURCE_DIR "/configs/grading";

json grade(const fs::path& rubric, const fs::path& submission, const std::string& tag) {
  const fs::path out = pinsim::test::temp_dir("grade-" + tag);
  const std::string cmd = std::string(PINSIM_BIN) + " -q grade --rubric " + rubric.string() +
                          " --submission " + submission.string() + " --out " + out.string() +
                          " > /dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  REQUIRE(WIFEXITED(status));
  REQUIRE(WEXITSTATUS(status) == 0);  // the grader never fails, whatever the submission does
  REQUIRE(fs::exists(out / "junit.xml"));
  REQUIRE(fs::exists(out / "summary.txt"));
  return json::parse(pinsim::test::read_file(out / "results.json"));
}

std::map<std::string, json> by_name(const json& results) {
  std::map<std::string, json> m;
  for (const auto& t : results["tests"]) m[t["name"].get<std::string>()] = t;
  return m;
}

// A folder holding copies of the given libraries: a "built library" submission.
fs::path library_folder(const std::string& tag, const std::vector<fs::path>& libs) {
  const fs::path d = pinsim::test::temp_dir("sub-" + tag);
  for (const auto& l : libs) fs::copy_file(l, d / l.filename());
  return d;
}

}  // namespace

TEST_CASE("grader: correct shipped plugins get full marks on the force assignment") {
  const fs::path plugins = PINSIM_BUILD_PLUGIN_DIR;
  const fs::path sub = library_folder("correct", {plugins / "libpinsim_plugin_linear_spring.so",
                                                  plugins / "libpinsim_plugin_damped_spring.so",
                                                  plugins / "libpinsim_plugin_bending.so"});
  const json r = grade(configs / "force_assignment.json", sub, "correct");
  CAPTURE(r["output"].get<std::string>());
  CHECK(r["max_score"].get<double>() > 0);
  CHECK(r["score"] == r["max_score"]);
  // Gradescope fields on every test.
  for (const auto& t : r["tests"])
    for (const char* k : {"name", "number", "score", "max_score", "status", "output", "visibility"})
      CHECK(t.contains(k));
}

TEST_CASE("grader: the force rubric tests every option of the shipped plugins") {
  // A bending plugin that ignores shape, rest_angle and length_scaled (flat rest shape only),
  // beside the shipped springs: full marks on everything but the option tests.
  const fs::path plugins = PINSIM_BUILD_PLUGIN_DIR;
  const fs::path sub = library_folder("flat", {plugins / "libpinsim_plugin_linear_spring.so",
                                               plugins / "libpinsim_plugin_damped_spring.so",
                                               subs / "flat_bending/libstudent_bending.so"});
  const json r = grade(configs / "force_assignment.json", sub, "flat");
  CAPTURE(r["output"].get<std::string>());
  auto tests = by_name(r);
  for (const char* t : {"bending: rest shape 'initial' agrees with the reference",
                        "bending: a rest angle agrees with the reference",
                        "bending: length-scaled stiffness agrees with the reference"}) {
    CAPTURE(t);
    CHECK(tests[t]["status"] == "failed");
    CHECK_THAT(tests[t]["output"].get<std::string>(), Contains("worst relative error"));
  }
  CHECK(tests["bending: agrees with the reference on random states"]["status"] == "passed");
  CHECK(tests["linear_spring: zero rest length agrees with the reference"]["status"] == "passed");
  CHECK(tests["damped_spring: strong damping and a given rest length agree with the reference"]
             ["status"] == "passed");
  // The fixture has no Jacobians either: df/dx (2) and df/dv (1) fail, as do the 3 option
  // tests (2 each): 68 - 9.
  CHECK(r["max_score"].get<double>() == 68);
  CHECK(r["score"].get<double>() == 59);
}

TEST_CASE("grader: a whole-body force (variable-length elements) is graded in the sandbox") {
  const fs::path plugins = PINSIM_BUILD_PLUGIN_DIR;
  const fs::path sub = library_folder("area", {plugins / "libpinsim_plugin_area_pressure.so"});
  const json r = grade(src / "rubric_area.json", sub, "area");
  CAPTURE(r["output"].get<std::string>());
  CHECK(r["max_score"].get<double>() == 4);
  CHECK(r["score"].get<double>() == 4);
}

TEST_CASE("grader: a source folder builds against an SDK package that lives under /tmp") {
  // The sandbox mounts the package at its own path; a path in /tmp (a CI clone there) needs
  // its folders made inside the sandbox's private /tmp, readable by the sandbox's uid.
  const fs::path prefix = "/tmp/pinsim-test-sdk-copy-" + std::to_string(::getpid());
  fs::remove_all(prefix);
  fs::copy(fs::path(PINSIM_BIN).parent_path().parent_path() / "sdk-package", prefix,
           fs::copy_options::recursive);
  const fs::path out = pinsim::test::temp_dir("grade-sdk-copy");
  const auto r = pinsim::test::shell(std::string(PINSIM_BIN) + " -q grade --rubric " +
                                     (src / "rubric_springs.json").string() + " --submission " +
                                     (src / "submissions/correct_source").string() + " --out " +
                                     out.string() + " --sdk-prefix " + prefix.string() + " 2>&1");
  CAPTURE(r.output);
  CHECK(r.code == 0);
  const json res = json::parse(pinsim::test::read_file(out / "results.json"));
  CHECK(res["score"].get<double>() == 10);
  fs::remove_all(prefix);
}

TEST_CASE("grader: each broken force submission gets its expected score and message") {
  const fs::path rubric = src / "rubric_springs.json";
  struct Case {
    std::string name;
    double score;
    std::vector<std::string> failed;  // tests that must fail
    std::string message;              // in the first failed test's output
  };
  const std::vector<Case> cases = {
      {"sign_error",
       3,
       {"f = -grad E", "df/dx", "agrees with the reference", "hanging chain"},
       "-dE/dx"},
      {"missing_half", 6, {"f = -grad E", "agrees with the reference"}, "does not converge"},
      {"wrong_jacobian", 9, {"df/dx"}, "df/dx"},
      {"nan_degenerate", 9, {"finite on degenerate states"}, "n"},
      // Omitting energy() loses the gradient check and the reference check (energies are
      // compared there), not just the gradient check.
      {"no_energy", 6, {"agrees with the reference", "f = -grad E"}, "your plugin has no energy()"},
      {"segfault", 1, {"f = -grad E", "hanging chain"}, "segmentation fault"},
      {"infinite_loop", 1, {"f = -grad E", "hanging chain"}, "limit"},
      {"huge_allocation", 1, {"f = -grad E", "hanging chain"}, "alloc"},
  };
  for (const auto& c : cases) {
    CAPTURE(c.name);
    const json r = grade(rubric, subs / c.name, c.name);
    CAPTURE(r["output"].get<std::string>());
    CHECK(r["max_score"].get<double>() == 10);
    CHECK(r["score"].get<double>() == c.score);
    auto tests = by_name(r);
    for (const auto& f : c.failed) {
      CAPTURE(f);
      CHECK(tests[f]["status"] == "failed");
      CHECK(tests[f]["score"].get<double>() == 0);
    }
    CHECK_THAT(tests[c.failed.front()]["output"].get<std::string>(), Contains(c.message));
  }
}

TEST_CASE("grader: a library of the wrong ABI fails every test, saying why") {
  const fs::path sub =
      library_folder("abi", {fs::path(PINSIM_TEST_FIXTURE_DIR) / "libfixture_wrong_abi.so"});
  const json r = grade(src / "rubric_springs.json", sub, "abi");
  CHECK(r["score"].get<double>() == 0);
  CHECK_THAT(r["tests"][0]["output"].get<std::string>(), Contains("wrong plugin ABI version"));
}

TEST_CASE("grader: a source folder that does not compile fails every test, the log once") {
  const json r =
      grade(src / "rubric_springs.json", src / "submissions/does_not_compile", "nobuild");
  CHECK(r["score"].get<double>() == 0);
  const std::string out = r["tests"][0]["output"].get<std::string>();
  CHECK_THAT(out, Contains("the submission does not compile"));
  CHECK_THAT(out, Contains("spring.cpp:8:3: error: expected"));  // the compiler's own words
  CHECK(r["tests"][1]["output"] == "not run: the submission does not compile, see test 1");
}

TEST_CASE("grader: a correct source folder is built against the SDK package and gets full marks") {
  const json r = grade(src / "rubric_springs.json", src / "submissions/correct_source", "source");
  CAPTURE(r["output"].get<std::string>());
  CHECK(r["score"].get<double>() == 10);
  CHECK(r["max_score"].get<double>() == 10);
}

TEST_CASE("grader: a submission's name cannot forge a row or shift columns of the batch CSV") {
  // File names are the students' own: "mallory\nalice,10.0,10.0" once added a row giving
  // alice 10.0 of 10.0, and "bob,10.0" put 10.0 in bob's score column. Names are written
  // percent-encoded ('%', ',', '"', control characters); each is graded as usual (3.0).
  const fs::path batch = pinsim::test::temp_dir("batch-names");
  for (const char* n : {"mallory\nalice,10.0,10.0", "bob,10.0"})
    fs::copy(subs / "sign_error", batch / n, fs::copy_options::recursive);
  const fs::path out = pinsim::test::temp_dir("batch-names-out");
  const std::string cmd = std::string(PINSIM_BIN) + " -q grade --batch --jobs 2 --rubric " +
                          (src / "rubric_springs.json").string() + " --submission " +
                          batch.string() + " --out " + out.string() + " > /dev/null 2>&1";
  REQUIRE(std::system(cmd.c_str()) == 0);
  CHECK(pinsim::test::read_file(out / "batch-0-of-1.csv") ==
        "submission,score,max_score\nbob%2C10.0,3.0,10.0\n"
        "mallory%0Aalice%2C10.0%2C10.0,3.0,10.0\n");
}

TEST_CASE("grader: batch mode grades a folder of submissions in shards") {
  const fs::path batch = pinsim::test::temp_dir("batch-in");
  for (const char* n : {"sign_error", "wrong_jacobian", "segfault"})
    fs::copy(subs / n, batch / n, fs::copy_options::recursive);
  const fs::path out = pinsim::test::temp_dir("batch-out");
  for (int shard = 0; shard < 2; ++shard) {
    const std::string cmd = std::string(PINSIM_BIN) + " -q grade --batch --jobs 2 --shard " +
                            std::to_string(shard) + "/2 --rubric " +
                            (src / "rubric_springs.json").string() + " --submission " +
                            batch.string() + " --out " + out.string() + " > /dev/null 2>&1";
    REQUIRE(std::system(cmd.c_str()) == 0);
  }
  // Shard 0 takes entries 0 and 2 (segfault, wrong_jacobian), shard 1 entry 1 (sign_error).
  CHECK(pinsim::test::read_file(out / "batch-0-of-2.csv") ==
        "submission,score,max_score\nsegfault,1.0,10.0\nwrong_jacobian,9.0,10.0\n");
  CHECK(pinsim::test::read_file(out / "batch-1-of-2.csv") ==
        "submission,score,max_score\nsign_error,3.0,10.0\n");
}
