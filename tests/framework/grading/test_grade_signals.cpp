// SIGTERM during `pinsim grade`: the grader finishes the test it is in, writes results.json
// with the tests done (score 0, saying why) and exits with 128 + 15.
#include <signal.h>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "test_support.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;
namespace fs = std::filesystem;

TEST_CASE("grade: SIGTERM finishes the current test and leaves valid results") {
  const fs::path out = test::temp_dir("grade-sigterm");
  // The infinite_loop submission passes "loads" at once and then hangs in test 2 until the
  // rubric's wall-clock limit (4 s).
  const pid_t pid = test::spawn_pinsim(
      {"-q", "grade", "--rubric", PINSIM_GRADING_SOURCE "/rubric_springs.json", "--submission",
       PINSIM_GRADING_SUBMISSIONS "/infinite_loop", "--out", (out / "results").string()},
      out / "log");
  REQUIRE(test::wait_until([&] {
    const auto r =
        nlohmann::json::parse(test::read_file(out / "results" / "results.json"), nullptr, false);
    return !r.is_discarded() && r.contains("tests") && r["tests"].size() >= 1;
  }));
  ::kill(pid, SIGTERM);
  CHECK(test::wait_pinsim(pid) == 143);
  const auto r = nlohmann::json::parse(test::read_file(out / "results" / "results.json"));
  CHECK(r["score"] == 0.0);
  CHECK(r["max_score"] == 10.0);
  // The signal lands while test 2 runs (it then fails at its time limit) or just before it
  // starts (then it is not run): either way the tests done are listed and nothing more.
  const std::size_t done = r["tests"].size();
  REQUIRE((done == 1 || done == 2));
  CHECK(r["tests"][0]["status"] == "passed");
  if (done == 2) CHECK(r["tests"][1]["status"] == "failed");
  CHECK(r["output"] == "Grading did not finish: the grader was interrupted (SIGTERM) after test " +
                           std::to_string(done) + " of 7. Please tell the course staff.");
}

TEST_CASE("grade --batch: SIGTERM is passed on, no more submissions start, no batch CSV") {
  const fs::path dir = test::temp_dir("batch-sigterm");
  for (const char* s : {"a", "b"}) {
    fs::create_directories(dir / "class" / s);
    fs::copy_file(PINSIM_GRADING_SUBMISSIONS "/infinite_loop/libstudent_spring.so",
                  dir / "class" / s / "libstudent_spring.so");
  }
  const pid_t pid = test::spawn_pinsim(
      {"grade", "--batch", "--jobs", "1", "--rubric", PINSIM_GRADING_SOURCE "/rubric_springs.json",
       "--submission", (dir / "class").string(), "--out", (dir / "out").string()},
      dir / "log");
  REQUIRE(test::wait_until([&] {
    const auto r =
        nlohmann::json::parse(test::read_file(dir / "out" / "a" / "results.json"), nullptr, false);
    return !r.is_discarded() && r.contains("tests") && r["tests"].size() >= 1;
  }));
  ::kill(pid, SIGTERM);
  CHECK(test::wait_pinsim(pid) == 143);
  const auto a = nlohmann::json::parse(test::read_file(dir / "out" / "a" / "results.json"));
  CHECK_THAT(a["output"].get<std::string>(),
             Contains("Grading did not finish: the grader was interrupted (SIGTERM) after test"));
  CHECK_FALSE(fs::exists(dir / "out" / "b"));
  CHECK_FALSE(fs::exists(dir / "out" / "batch-0-of-1.csv"));
  CHECK_THAT(test::read_file(dir / "log"),
             Contains("grading stopped by SIGTERM: 1 of this shard's 2 submission(s) started"));
}
