// The collision rubric (configs/grading/collision_assignment.json) on fixture backends: a
// correct one gets full marks; a discrete-only one fails every tunnelling test; backends
// that do not move the balls, put them back or stop them score at most 10 %, whatever they
// report; each stage's failure names the step and the closed form or reference it missed.
#include <sys/wait.h>

#include <catch2/catch.hpp>
#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "test_support.hpp"

using Catch::Matchers::Contains;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const fs::path subs = PINSIM_GRADING_SUBMISSIONS;
const fs::path rubric = PINSIM_SOURCE_DIR "/configs/grading/collision_assignment.json";

json grade(const fs::path& submission, const std::string& tag) {
  const fs::path out = pinsim::test::temp_dir("collision-" + tag);
  const std::string cmd = std::string(PINSIM_BIN) + " -q grade --rubric " + rubric.string() +
                          " --submission " + submission.string() + " --out " + out.string() +
                          " > /dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  REQUIRE(WIFEXITED(status));
  REQUIRE(WEXITSTATUS(status) == 0);
  return json::parse(pinsim::test::read_file(out / "results.json"));
}

std::map<std::string, json> by_name(const json& results) {
  std::map<std::string, json> m;
  for (const auto& t : results["tests"]) m[t["name"].get<std::string>()] = t;
  return m;
}

std::string out(const json& test) { return test["output"].get<std::string>(); }

const std::vector<std::string> kTunnelling = {
    "thin box and capsule walls at 10 units/s: no tunnelling, no penetration",
    "thin box and capsule walls at 1,000 units/s: no tunnelling",
    "thin box and capsule walls at 100,000 units/s: no tunnelling",
    "channel of thin boxes, four hits per step: no tunnelling"};

}  // namespace

TEST_CASE("collision rubric: the sdf backend under the student's name gets full marks") {
  const json r = grade(subs / "correct_backend", "correct");
  CAPTURE(r["output"].get<std::string>());
  for (const auto& t : r["tests"]) {
    CAPTURE(t["name"].get<std::string>(), out(t));
    CHECK(t["status"] == "passed");
  }
  CHECK(r["max_score"].get<double>() == 36);
  CHECK(r["score"] == r["max_score"]);
  auto t = by_name(r);
  CHECK_THAT(out(t["free flight: every step equals symplectic Euler's closed form"]),
             Contains("largest difference from the closed form"));
  CHECK_THAT(out(t["channel of thin boxes: every collision of a step, path of the reference"]),
             Contains("the path follows the reference's for all 25 steps"));
}

TEST_CASE("collision rubric: the reference solution, built from source, gets full marks") {
  // tests/pinball_reference: sphere tracing against phi - r with depthMin, every collision
  // of a step (capped), impulses only while approaching, with the surface's velocity; built
  // by the grader in its sandbox against the SDK package, as a student's folder is.
  const json r = grade(PINSIM_SOURCE_DIR "/tests/pinball_reference", "reference");
  CAPTURE(r["output"].get<std::string>());
  for (const auto& t : r["tests"]) {
    CAPTURE(t["name"].get<std::string>(), out(t));
    CHECK(t["status"] == "passed");
  }
  CHECK(r["max_score"].get<double>() == 36);
  CHECK(r["score"] == r["max_score"]);
}

TEST_CASE("collision rubric: the unmodified starter kit scores well under half") {
  const json r = grade(PINSIM_SOURCE_DIR "/sdk/pinball_starter", "starter");
  CAPTURE(r["output"].get<std::string>());
  auto t = by_name(r);
  CHECK(t["loads as a collision backend"]["status"] == "passed");
  CHECK(t["free flight: every step equals symplectic Euler's closed form"]["status"] == "passed");
  for (const auto& name : kTunnelling) {
    CAPTURE(name, out(t[name]));
    CHECK(t[name]["status"] == "failed");
  }
  CHECK(t["swinging flipper: outgoing velocity with the flipper's surface velocity"]["status"] ==
        "failed");
  CHECK(r["score"].get<double>() <= 0.25 * r["max_score"].get<double>());
}

TEST_CASE("collision rubric: a discrete-only backend fails every tunnelling test") {
  // The assignment's starter: drift, one check of the SDF at the end of the step.
  const json r = grade(subs / "discrete_backend", "discrete");
  CAPTURE(r["output"].get<std::string>());
  auto t = by_name(r);
  for (const auto& name : kTunnelling) {
    CAPTURE(name, out(t[name]));
    CHECK(t[name]["status"] == "failed");
  }
  // At 10 units/s the ball ends a step 0.01 deep; at 1,000 it ends on the wall's far side.
  CHECK_THAT(out(t[kTunnelling[0]]), Contains("inside obstacle"));
  CHECK_THAT(out(t[kTunnelling[1]]), Contains("the reference's at"));
  CHECK_THAT(out(t[kTunnelling[1]]), Contains("at step 3 "));
  // Free flight is the starter's own, and is exact.
  CHECK(t["free flight: every step equals symplectic Euler's closed form"]["status"] == "passed");
  CHECK(r["score"].get<double>() < r["max_score"].get<double>() / 2);

  const json drift = grade(subs / "tunnelling_backend", "drift");
  auto d = by_name(drift);
  for (const auto& name : kTunnelling) {
    CAPTURE(name, out(d[name]));
    CHECK(d[name]["status"] == "failed");
  }
}

TEST_CASE("collision rubric: a backend that holds the balls scores at most 10 %") {
  // Each reports the reference's contacts; none moves the balls the way free flight does.
  for (const char* sub : {"still_backend", "put_back_backend", "stop_backend"}) {
    CAPTURE(sub);
    const json r = grade(subs / sub, sub);
    CAPTURE(r["output"].get<std::string>());
    CHECK(r["score"].get<double>() <= 0.1 * r["max_score"].get<double>());
    auto t = by_name(r);
    CHECK(t["loads as a collision backend"]["status"] == "passed");
    CHECK_THAT(out(t["free flight: every step equals symplectic Euler's closed form"]),
               Contains("at step "));
    CHECK_THAT(out(t["one slow bounce: outgoing velocity v' = v - (1 + e) vn n"]),
               Contains("motion gate"));
  }
}

TEST_CASE("collision rubric: an impulse while separating fails the approach tests") {
  const json sep = grade(subs / "separating_backend", "separating");
  CAPTURE(sep["output"].get<std::string>());
  auto s = by_name(sep);
  CHECK(s["ball leaving a floor: no impulse while separating"]["status"] == "failed");
  CHECK_THAT(out(s["ball leaving a floor: no impulse while separating"]),
             Contains("while separating"));
}

TEST_CASE("collision rubric: backend_approaching_only measures impulses, not the reports") {
  // Each forgery is the reference backend plus one push, in the first step, to a ball that
  // is already leaving the floor: only "ball leaving a floor" may fail, with the grader's
  // measurement named in the message, whatever the submission reports about the push.
  const std::string name = "ball leaving a floor: no impulse while separating";
  const std::vector<std::pair<std::string, std::string>> forgeries = {
      {"silent_push_backend", "with no contact reported"},
      {"false_approach_backend", "but the grader measured"},
      {"nan_report_backend", "non-finite"}};
  for (const auto& [sub, message] : forgeries) {
    const json r = grade(subs / sub, sub);
    CAPTURE(sub);
    CAPTURE(r["output"].get<std::string>());
    auto t = by_name(r);
    CHECK(t[name]["status"] == "failed");
    CHECK_THAT(out(t[name]), Contains(message));
    CHECK_THAT(out(t[name]), Contains("at step 1 particle 0"));
    CHECK(r["score"].get<double>() ==
          r["max_score"].get<double>() - t[name]["max_score"].get<double>());
  }
}
