// What the grader writes, checked as a student and Gradescope see it: results.json against
// Gradescope's documented format (gradescope_results.schema.json, by check_results.py) for
// passing, failing, crashed, timed-out, not-compiled, interrupted and refused gradings; a
// cause stated once (a build that failed, a missing plugin), with no physics hint on a test
// that could not run; visibility and stdout visibility from the rubric; and check-plugin's
// count of skipped checks (--strict, --rubric) against the grader's verdicts.
#include <signal.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "grade_cli.hpp"
#include "test_support.hpp"

using Catch::Matchers::Contains;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const fs::path subs = PINSIM_GRADING_SUBMISSIONS;
const fs::path src = PINSIM_GRADING_SOURCE;
const fs::path plugins = PINSIM_BUILD_PLUGIN_DIR;

using pinsim::test::grade;
using pinsim::test::Graded;

fs::path library_folder(const std::string& tag, const std::vector<fs::path>& libs) {
  const fs::path d = pinsim::test::temp_dir("results-sub-" + tag);
  for (const auto& l : libs) fs::copy_file(l, d / l.filename());
  return d;
}

std::string output(const json& r, std::size_t i) {
  return r["tests"][i]["output"].get<std::string>();
}

/// check_results.py on these files: exit 0 when each is valid and broken ones are rejected.
pinsim::test::CommandResult validate(const std::vector<fs::path>& files) {
  std::string cmd = "/usr/bin/python3 " + (src / "check_results.py").string();
  for (const auto& f : files) {
    cmd += ' ';
    cmd += f.string();
  }
  cmd += " 2>&1";
  return pinsim::test::shell(cmd);
}

}  // namespace

TEST_CASE("results: every kind of grading gives a results.json of Gradescope's format") {
  const fs::path springs = src / "rubric_springs.json";
  std::vector<fs::path> files;
  const Graded passing = grade(
      springs, library_folder("pass", {plugins / "libpinsim_plugin_linear_spring.so"}), "passing");
  CHECK(passing.results["score"] == 10);
  files.push_back(passing.file);
  const Graded failing = grade(springs, subs / "sign_error", "failing");
  CHECK(failing.results["score"] == 3);
  files.push_back(failing.file);
  const Graded crashed = grade(springs, subs / "segfault", "crashed");
  CHECK_THAT(crashed.results.dump(), Contains("segmentation fault"));
  files.push_back(crashed.file);
  const Graded timed_out = grade(springs, subs / "infinite_loop", "timed_out");
  CHECK_THAT(timed_out.results.dump(), Contains("limit"));
  files.push_back(timed_out.file);
  const Graded no_build = grade(springs, src / "submissions/does_not_compile", "no_build");
  CHECK(no_build.results["score"] == 0);
  files.push_back(no_build.file);

  // Interrupted: SIGTERM while test 2 hangs; the file lists the tests done.
  const fs::path dir = pinsim::test::temp_dir("results-interrupted");
  const pid_t pid = pinsim::test::spawn_pinsim(
      {"-q", "grade", "--rubric", springs.string(), "--submission",
       (subs / "infinite_loop").string(), "--out", (dir / "out").string()},
      dir / "log");
  REQUIRE(pinsim::test::wait_until([&] {
    const auto r =
        json::parse(pinsim::test::read_file(dir / "out" / "results.json"), nullptr, false);
    return !r.is_discarded() && r.contains("tests") && r["tests"].size() >= 1;
  }));
  ::kill(pid, SIGTERM);
  CHECK(pinsim::test::wait_pinsim(pid) == 143);
  const json interrupted = json::parse(pinsim::test::read_file(dir / "out" / "results.json"));
  CHECK_THAT(interrupted["output"].get<std::string>(), Contains("interrupted (SIGTERM)"));
  files.push_back(dir / "out" / "results.json");

  // Refused: the rubric is invalid (the grader's own failure, no tests).
  const fs::path bad = pinsim::test::temp_dir("results-bad-rubric");
  pinsim::test::write_file(bad / "rubric.json", R"({"tests": [{"name": "x"}]})");
  const Graded refused = grade(bad / "rubric.json", subs / "sign_error", "refused");
  CHECK(refused.code == 2);
  CHECK(refused.results["tests"].empty());
  files.push_back(refused.file);

  const auto v = validate(files);
  INFO(v.output);
  CHECK(v.code == 0);
  CHECK_THAT(v.output, Contains("7 results files validated"));
  // The validator fails on a file that is not of the format.
  const fs::path wrong = pinsim::test::temp_dir("results-wrong") / "results.json";
  json w = failing.results;
  w["tests"][0]["status"] = "error";
  pinsim::test::write_file(wrong, w.dump());
  const auto vw = validate({wrong});
  CHECK(vw.code == 1);
  CHECK_THAT(vw.output, Contains("tests/0/status"));
}

TEST_CASE("results: a build that failed is said once, with no hint, on the first visible test") {
  const Graded g = grade(src / "rubric_springs.json", src / "submissions/does_not_compile", "once");
  const json& r = g.results;
  REQUIRE(r["tests"].size() == 7);
  const std::string first = output(r, 0);
  CHECK_THAT(first, Contains("the submission does not compile"));
  CHECK_THAT(first, Contains("spring.cpp:8:3: error: expected"));
  for (std::size_t i = 1; i < 7; ++i) {
    CAPTURE(i);
    CHECK(output(r, i) == "not run: the submission does not compile, see test 1");
  }
  // No physics hint where nothing ran ("f = -grad E" has one), and the top-level output
  // is the score and one line per test, not the tests' outputs again.
  CHECK(r.dump().find("Hint:") == std::string::npos);
  const std::string top = r["output"].get<std::string>();
  CHECK(top.find("error: expected") == std::string::npos);
  CHECK_THAT(top, Contains("0 / 10 points, 0 of 7 tests passed"));
  // The log appears once in the whole file.
  const std::string all = r.dump();
  CHECK(all.find("spring.cpp:8:3") == all.rfind("spring.cpp:8:3"));
}

TEST_CASE("results: a missing plugin is said once, and visibility comes from the rubric") {
  // Top level after_due_date, stdout visible; test 1 inherits after_due_date, test 2 says
  // visible: the cause goes on test 2, which the student sees before the due date.
  const fs::path dir = pinsim::test::temp_dir("results-visibility");
  pinsim::test::write_file(
      dir / "rubric.json",
      R"({"name": "visibility", "kind": "force", "visibility": "after_due_date",
          "stdout_visibility": "visible",
          "limits": {"cpu_seconds": 2, "memory_mb": 512, "wall_seconds": 4},
          "tests": [
            {"name": "loads", "check": "load", "plugin": "linear_spring"},
            {"name": "f = -grad E", "check": "gradient", "plugin": "linear_spring",
             "visibility": "visible", "hint": "Check the sign."},
            {"name": "hidden one", "check": "momentum", "plugin": "linear_spring",
             "visibility": "hidden"}]})");
  const Graded g =
      grade(dir / "rubric.json",
            library_folder("missing", {plugins / "libpinsim_plugin_damped_spring.so"}), "missing");
  const json& r = g.results;
  CHECK(r["visibility"] == "after_due_date");
  CHECK(r["stdout_visibility"] == "visible");
  REQUIRE(r["tests"].size() == 3);
  CHECK(r["tests"][0]["visibility"] == "after_due_date");
  CHECK(r["tests"][1]["visibility"] == "visible");
  CHECK(r["tests"][2]["visibility"] == "hidden");
  CHECK(output(r, 0) == "not run: the submission has no plugin 'linear_spring', see test 2");
  CHECK_THAT(output(r, 1),
             Contains("no library of the submission declares plugin 'linear_spring'"));
  CHECK_THAT(output(r, 1), Contains("declares plugin 'damped_spring'"));
  CHECK(output(r, 2) == "not run: the submission has no plugin 'linear_spring', see test 2");
  CHECK(r.dump().find("Hint:") == std::string::npos);
  const auto v = validate({g.file});
  INFO(v.output);
  CHECK(v.code == 0);
}

TEST_CASE("results: the rubric's visibility values are checked, naming the JSON path") {
  const fs::path dir = pinsim::test::temp_dir("results-bad-visibility");
  for (const auto& [key, where] : std::vector<std::pair<std::string, std::string>>{
           {R"("stdout_visibility": "students")", "stdout_visibility"},
           {R"("visibility": "always")", "visibility"}}) {
    CAPTURE(key);
    pinsim::test::write_file(dir / "rubric.json",
                             "{" + key +
                                 R"(, "tests": [{"name": "a", "check": "load", "plugin": "x",
                                                 "visibility": "later"}]})");
    const auto r = pinsim::test::pinsim_cli("-q grade --rubric " + (dir / "rubric.json").string() +
                                            " --submission " + (subs / "sign_error").string() +
                                            " --out " + (dir / "out").string() + " 2>&1");
    CHECK(r.code == 2);
    CHECK_THAT(r.output, Contains("rubric.json: " + where +
                                  ": expected visible, hidden, after_due_date or after_published"));
  }
  pinsim::test::write_file(
      dir / "rubric.json",
      R"({"tests": [{"name": "a", "check": "load", "plugin": "x", "visibility": "later"}]})");
  const auto r = pinsim::test::pinsim_cli("-q grade --rubric " + (dir / "rubric.json").string() +
                                          " --submission " + (subs / "sign_error").string() +
                                          " --out " + (dir / "out").string() + " 2>&1");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("rubric.json: tests[0].visibility: expected visible, hidden, "
                                "after_due_date or after_published, got \"later\""));
}

TEST_CASE("check-plugin: skipped checks are counted, failed with --strict, named by --rubric") {
  // A correct spring that forgets PINSIM_CAP_INTERNAL: momentum, angular momentum and rigid
  // invariance are skipped (dfdv and dissipation too: it has neither); the grader's "forces
  // sum to zero" (momentum) fails on it.
  const fs::path lib = subs / "table_no_internal_flag/libstudent_spring.so";
  const std::string skipped =
      "5 skipped (dfdv, momentum, angular_momentum, rigid_invariance, dissipation)";
  const auto plain = pinsim::test::pinsim_cli("check-plugin " + lib.string() + " -p k=10 2>&1");
  INFO(plain.output);
  CHECK(plain.code == 0);
  CHECK_THAT(plain.output, Contains("PASS: linear_spring"));
  CHECK_THAT(plain.output, Contains(skipped));
  CHECK_THAT(plain.output, Contains("pinsim grade fails a skipped check where its rubric"));

  const auto strict =
      pinsim::test::pinsim_cli("check-plugin " + lib.string() + " -p k=10 --strict 2>&1");
  INFO(strict.output);
  CHECK(strict.code == 1);
  CHECK_THAT(strict.output, Contains("FAIL (--strict): linear_spring, 5 check(s) skipped"));

  const fs::path rubric = src / "rubric_springs.json";
  const auto scored = pinsim::test::pinsim_cli("check-plugin " + lib.string() +
                                               " -p k=10 --rubric " + rubric.string() + " 2>&1");
  INFO(scored.output);
  CHECK(scored.code == 1);
  CHECK_THAT(scored.output,
             Contains("scored by the grader: test 4 \"forces sum to zero\" (1 point) of rubric "
                      "\"grader test: linear_spring\" runs momentum, skipped here"));
  CHECK_THAT(scored.output, Contains("FAIL: linear_spring, 1 skipped check(s) scored by rubric"));

  const auto js = pinsim::test::pinsim_cli("check-plugin " + lib.string() +
                                           " -p k=10 --json --rubric " + rubric.string());
  CHECK(js.code == 1);
  const json j = json::parse(js.output);
  CHECK(j["passed"] == false);
  CHECK(j["skipped"] ==
        json({"dfdv", "momentum", "angular_momentum", "rigid_invariance", "dissipation"}));
  REQUIRE(j["scored_skips"].size() == 1);
  CHECK(j["scored_skips"][0]["test"] == 4);

  // The grader agrees: that test fails, saying the check was not run, and the rest pass.
  const Graded g = grade(rubric, lib.parent_path(), "no_internal");
  CHECK(g.results["score"] == 9);
  CHECK(g.results["tests"][3]["status"] == "failed");
  CHECK_THAT(output(g.results, 3), Contains("not checked: not an internal force"));
}
