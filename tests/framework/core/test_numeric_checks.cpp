// Numerical failures caught in the step where they start, naming the particle and the
// plugin involved, with readable numbers; legitimate motion never trips the checks.
#include <catch2/catch.hpp>
#include <regex>
#include <string>

#include "core/format.hpp"
#include "core/runner.hpp"
#include "core/scene.hpp"
#include "test_support.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

namespace {

// The stress sweep's spring (configs/stress/springs.json): particle 0 pinned, particle 1 of
// mass 1 on a spring k = 1600, L = 1, stretched by 0.2, w = sqrt(k / m) = 40. At dt = 0.24,
// h w = 9.6: symplectic Euler multiplies the energy by lambda^2 ~ 8000 per step
// (lambda + 1/lambda = (h w)^2 - 2 = 90.2).
std::string stiff_spring(const std::string& checks = "") {
  return R"({"time": {"dt": 0.24, "duration": 20.0},
    "particles": [{"x": [0, 0], "pinned": true}, {"x": [1.2, 0], "v": [0, 0.3]}],
    "forces": [{"type": "linear_spring", "params": {"k": 1600.0, "rest_length": 1.0},
                "elements": [[0, 1]]}])" +
         checks + "}";
}

// A hanging strand of `count` particles of 0.01 kg, root pinned, springs ks between them.
std::string strand(double dt, double ks, const std::string& integrator) {
  return R"({"time": {"dt": )" + num(dt) + R"(, "duration": 1.0},
    "integrator": ")" +
         integrator + R"(",
    "bodies": [{"type": "strand", "name": "hair", "root": [0, 1], "direction": [1, 0],
                "count": 8, "segment_length": 0.08, "mass": 0.01, "pin_root": true}],
    "forces": [{"type": "gravity"},
               {"type": "damped_spring", "params": {"ks": )" +
         num(ks, 17) + R"(, "kd": 0.05},
                "elements": {"body": "hair", "set": "edges"}}]})";
}

RunResult run(const std::string& text, const std::vector<std::string>& set = {}) {
  PluginLoader loader(plugin_search_dirs());
  return run_scene(parse_scene(text, "scene.json", ".", set), loader, {});
}

// No number printed with more than 7 significant digits ("%.6g" gives at most 6).
bool readable(const std::string& message) {
  return !std::regex_search(message, std::regex("[0-9]{8,}"));
}

}  // namespace

TEST_CASE("numeric checks: an unstable stiff spring stops at its second step") {
  test::FpTrapsOff traps;  // the run overflows on purpose when the check is off
  const RunResult r = run(stiff_spring());
  CHECK(r.exit_code == 1);
  const auto& e = r.summary["error"];
  CHECK(e["kind"] == "numeric");
  CHECK(e["numeric"] == "energy_blowup");
  // Step 1 is not checked (no earlier step); step 1 gives v = -h k 0.2 = -76.8, so
  // K^1 = (76.8^2 + 0.3^2) / 2 = 2949.165, and step 2 gives x = 1.2 - 0.24 * 76.8 = -17.232,
  // a stretch of 16.232 and v = -76.8 + 0.24 * 1600 * 16.232... = 6156.3, K = 1.895e7, past
  // 32 (K^1 + S) = 32 * 2 * 2949.165.
  CHECK(e["step"] == 2);
  CHECK(e["t"].get<double>() == Approx(0.48));
  CHECK(e["particle"] == 1);
  CHECK(e["plugin"] == "forces[0] 'linear_spring'");
  const std::string m = e["message"];
  CHECK_THAT(m, StartsWith("energy blow-up: the kinetic energy of particle 1 grew from 2949.16 "
                           "to 1.8950"));
  CHECK_THAT(m, Contains("past 32 x (its energy + the energy scale 2949.16)") &&
                    Contains("(checks.kinetic_growth = 32); largest force on it: forces[0] "
                             "'linear_spring' (|f| = "));
  CHECK(readable(m));
}

TEST_CASE("numeric checks: the stiff spring from the command line, exit status 1") {
  const auto dir = test::temp_dir("stiff");
  test::write_file(dir / "stiff.json", stiff_spring());
  const auto r =
      test::pinsim_cli("run " + (dir / "stiff.json").string() + " --out " + (dir / "out").string());
  CHECK(r.code == 1);
  CHECK_THAT(r.output, Contains("[error]") &&
                           Contains("stiff.json: step 2 (t = 0.48), particle 1, forces[0] "
                                    "'linear_spring': energy blow-up: the kinetic energy of "
                                    "particle 1 grew"));
  const auto s = nlohmann::json::parse(test::read_file(dir / "out" / "summary.json"));
  CHECK(s["status"] == "error");
  CHECK(s["steps"] == 1);
  CHECK(s["error"]["plugin"] == "forces[0] 'linear_spring'");
  CHECK(s["error"]["particle"] == 1);
  CHECK(s["error"]["step"] == 2);
  CHECK(s["error"]["numeric"] == "energy_blowup");
}

TEST_CASE("numeric checks: kinetic_growth 0 turns the per-step bound off") {
  test::FpTrapsOff traps;
  // Then the overflow stops it, late: at step 81 the spring's force is NaN at both ends,
  // and the free end is named.
  const RunResult r = run(stiff_spring(R"(, "checks": {"kinetic_growth": 0})"));
  CHECK(r.exit_code == 1);
  const auto& e = r.summary["error"];
  CHECK(e["step"] == 81);
  CHECK(e["numeric"] == "non_finite");
  CHECK(e["particle"] == 1);
  CHECK(e["plugin"] == "forces[0] 'linear_spring'");
}

TEST_CASE("numeric checks: a NaN made in the backend's drift is blamed on the backend") {
  // The fixture backend's 3rd drift sets particle 0's v_x to NaN; every force (gravity) is
  // finite and the velocity entered the drift finite, so the backend is to blame.
  test::FpTrapsOff traps;  // the checks compare the NaN (an invalid operation) on purpose
  const Scene scene = parse_scene(R"({"plugin_path": [")" PINSIM_TEST_FIXTURE_DIR R"("],
    "time": {"dt": 0.01, "duration": 1.0}, "integrator": "symplectic_euler",
    "backend": {"name": "disc_backend", "params": {"nan_step": 3}},
    "particles": [{"x": [0, 0], "v": [1, 0]}], "forces": [{"type": "gravity"}]})",
                                  "scene.json", ".", {});
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  const RunResult r = run_scene(scene, loader, {});
  CHECK(r.exit_code == 1);
  const auto& e = r.summary["error"];
  CHECK(e["kind"] == "numeric");
  CHECK(e["numeric"] == "non_finite");
  CHECK(e["step"] == 3);
  CHECK(e["particle"] == 0);
  CHECK(e["plugin"] == "backend 'disc_backend'");
  CHECK_THAT(e["message"].get<std::string>(),
             StartsWith("non-finite state of particle 0 after the drift by backend "
                        "'disc_backend': x = ") &&
                 Contains("; it entered the drift finite, at v = "));
  CHECK(r.summary["steps"] == 2);
}

TEST_CASE("numeric checks: kinetic_growth must be 0 or at least 2") {
  PluginLoader loader(plugin_search_dirs());
  REQUIRE_THROWS_WITH(
      parse_scene(stiff_spring(R"(, "checks": {"kinetic_growth": 1.5})"), "s.json", "."),
      Contains("checks.kinetic_growth") && Contains("must be 0 (off) or a number >= 2, got 1.5"));
}

TEST_CASE("numeric checks: a spring chain at too large a dt names the spring plugin") {
  test::FpTrapsOff traps;
  // ks = 1000 on 0.01 kg: w = 316 per spring, up to 2 w = 632 for the chain; dt = 0.01
  // gives h w_max = 6.3, an energy growth of some (h w)^4 ~ 1600 per step in the fastest
  // mode, which starts small (the strand is released straight, at rest) and overtakes the
  // energy scale within a few steps. Without the bound: step 100 (the total-energy check).
  const RunResult r = run(strand(0.01, 1000.0, "symplectic_euler"));
  CHECK(r.exit_code == 1);
  const auto& e = r.summary["error"];
  CHECK(e["numeric"] == "energy_blowup");
  CHECK(e["step"].get<int>() <= 8);
  CHECK(e["particle"].get<int>() >= 1);  // never the pinned root
  CHECK(e["plugin"] == "forces[1] 'damped_spring'");
  CHECK(readable(e["message"].get<std::string>()));
  // At dt = 0.001, h w_max = 0.63: stable, and the checks stay quiet.
  CHECK(run(strand(0.001, 1000.0, "symplectic_euler")).exit_code == 0);
}

TEST_CASE("numeric checks: total-energy blow-up names the particle and plugin, readably") {
  test::FpTrapsOff traps;
  // Growth of 34 per step (the run-output test's spring at h w = 2.83) is under the per-step
  // bound (2 G = 64 when one particle holds the energy); the total-energy check catches it.
  const std::string scene = R"({"time": {"dt": 0.02, "duration": 2.0},
      "particles": [{"x": [0, 0], "pinned": true}, {"x": [0.1, 0], "v": [0, 0.5]}],
      "forces": [{"type": "gravity", "params": {"g": [0, -1]}},
                 {"type": "linear_spring", "params": {"k": 2e4, "rest_length": 0},
                  "elements": [[0, 1]]}],
      "checks": {"energy_blowup": 1000, "energy_every": 1}})";
  const RunResult r = run(scene);
  CHECK(r.exit_code == 1);
  const auto& e = r.summary["error"];
  CHECK(e["numeric"] == "energy_blowup");
  CHECK(e["particle"] == 1);
  CHECK(e["plugin"] == "forces[1] 'linear_spring'");
  const std::string m = e["message"];
  CHECK_THAT(m, StartsWith("energy blow-up: E = ") &&
                    Contains("limit checks.energy_blowup = 1000); particle 1 gained the most "
                             "kinetic energy since the last check") &&
                    Contains("largest force on it: forces[1] 'linear_spring'"));
  CHECK(readable(m));
}

TEST_CASE("numeric checks: implicit Euler with ks = 1e100 is the solver's failure") {
  // (1e100 is the largest parameter a scene may give: the limit of value_limits.hpp)
  test::FpTrapsOff traps;
  const RunResult r = run(strand(0.001, 1e100, "implicit_euler"));
  CHECK(r.exit_code == 1);
  const auto& e = r.summary["error"];
  CHECK(e["numeric"] == "solver_failure");
  CHECK(e["plugin"] == "forces[1] 'damped_spring'");
  CHECK(e["particle"].get<int>() >= 1);
  const std::string m = e["message"];
  CHECK_THAT(m, StartsWith("implicit_euler: the linear solve cannot be trusted") &&
                    Contains("too ill-conditioned for double precision") &&
                    Contains("stiffest force: forces[1] 'damped_spring'"));
  CHECK_THAT(m, !Contains("backend"));
  CHECK(readable(m));
  // A stiff but representable chain passes: ks = 1e7, (h w)^2 = 1e-6 * 1e9 = 1e3.
  CHECK(run(strand(0.001, 1e7, "implicit_euler")).exit_code == 0);
}

TEST_CASE("numeric checks: legitimate motion stays inside the growth bound") {
  // Free fall from rest at y = 0, where the initial energy scale is 0: K grows as n^2, a
  // factor ((n + 1) / n)^2 <= 4 per step from the second step on, inside G (K + S) even at
  // the smallest G = 2 because S >= K.
  const std::string fall = R"({"time": {"dt": 0.01, "duration": 2.0},
      "particles": [{"x": [0, 0], "mass": 1000}], "forces": [{"type": "gravity"}],
      "checks": {"kinetic_growth": 2}})";
  CHECK(run(fall).exit_code == 0);
  // A spring released from its stretch just inside symplectic Euler's limit h w < 2
  // (h w = 1.98): its energy swings by (h w)^2 / 4 ~ 1 of the scale but stays bounded.
  const std::string spring = R"({"time": {"dt": 0.0495, "duration": 20.0},
      "particles": [{"x": [0, 0], "pinned": true}, {"x": [1.5, 0]}],
      "forces": [{"type": "linear_spring", "params": {"k": 1600.0, "rest_length": 1.0},
                  "elements": [[0, 1]]}]})";
  CHECK(run(spring).exit_code == 0);
  // The same at RK4's limit h w < 2.83 (h w = 2.8).
  CHECK(run(spring, {"time.dt=0.07", "integrator=rk4"}).exit_code == 0);
}

namespace {

// xpbd in 4 substeps on three particles (0 pinned) joined by the wrong_constraint fixture's
// spring (elements [0, 1] and [2, 1]) with `mistake`, gravity as an external force, on
// `backend`.
RunResult xpbd_chain(const std::string& mistake, const std::string& backend) {
  const Scene scene = parse_scene(R"({"plugin_path": [")" PINSIM_TEST_FIXTURE_DIR R"("],
    "time": {"dt": 0.01, "duration": 0.1}, "integrator": "xpbd",
    "xpbd": {"substeps": 4, "iterations": 1}, "backend": )" +
                                      backend + R"(,
    "particles": [{"x": [0, 0], "pinned": true}, {"x": [1, 0], "v": [1, 0]}, {"x": [2, 0]}],
    "forces": [{"type": "gravity"},
               {"type": "wrong_constraint",
                "library": ")" PINSIM_TEST_FIXTURE_DIR R"(/libfixture_wrong_constraint.so",
                "params": {"k": 100, "mistake": ")" +
                                      mistake + R"("}, "elements": [[0, 1], [2, 1]]}]})",
                                  "scene.json", ".", {});
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  return run_scene(scene, loader, {});
}

}  // namespace

TEST_CASE("numeric checks: xpbd blames a NaN made in a constraint projection on its plugin") {
  // The fixture's C (or dC/dp) of element 1, particles (2, 1), is NaN while its force stays
  // finite: the projection of that element in the first substep makes the position of its
  // first particle NaN, and the run names the plugin, the element and the particle there
  // (before, the NaN reached the velocity and was blamed on the backend's drift).
  test::FpTrapsOff traps;  // the fixture makes a NaN on purpose
  for (const std::string mistake : {"nan_c", "nan_gradient"}) {
    CAPTURE(mistake);
    const RunResult r = xpbd_chain(mistake, R"("none")");
    CHECK(r.exit_code == 1);
    const auto& e = r.summary["error"];
    CHECK(e["kind"] == "numeric");
    CHECK(e["numeric"] == "non_finite");
    CHECK(e["step"] == 1);
    CHECK(e["particle"] == 2);
    CHECK(e["plugin"] == "forces[1] 'wrong_constraint'");
    CHECK_THAT(e["message"].get<std::string>(),
               StartsWith("non-finite position of particle 2 from xpbd's projection of "
                          "forces[1] 'wrong_constraint' element 1 (particles 2, 1; C = ") &&
                   Contains("at x = (2, 0), v = (0, "));
    CHECK(r.summary["steps"] == 0);
  }
}

TEST_CASE("numeric checks: xpbd blames a NaN made in a substep's drift on the backend") {
  // The fixture backend's 3rd drift (substep 3 of step 1) makes particle 0's v_x NaN; the
  // check after that drift stops the step there, before substep 4's projection (with a
  // correct constraint entry) would carry the NaN into positions and blame the constraint.
  test::FpTrapsOff traps;
  const RunResult r = xpbd_chain("none", R"({"name": "disc_backend", "params": {"nan_step": 3}})");
  CHECK(r.exit_code == 1);
  const auto& e = r.summary["error"];
  CHECK(e["numeric"] == "non_finite");
  CHECK(e["step"] == 1);
  CHECK(e["particle"] == 0);
  CHECK(e["plugin"] == "backend 'disc_backend'");
  CHECK_THAT(e["message"].get<std::string>(),
             StartsWith("non-finite state of particle 0 after the drift by backend "
                        "'disc_backend': x = ") &&
                 Contains("; it entered the drift finite, at v = (0, "));
}
