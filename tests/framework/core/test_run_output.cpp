// Output files: complete, valid and kept when a run ends early (NaN, interrupt).
#include <catch2/catch.hpp>
#include <csignal>
#include <fstream>
#include <sstream>

#include "core/runner.hpp"
#include "core/scene.hpp"
#include "test_support.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;
namespace fs = std::filesystem;

namespace {

std::vector<std::string> lines(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> out;
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

// Three particles moving right at 1, 2, 3 units/s; the nan_force fixture turns particle
// `bad` non-finite once its x passes 1.0.
std::string nan_scene(int bad) {
  return R"({
    "time": {"dt": 0.01, "duration": 2.0},
    "particles": [{"x": [0, 0], "v": [1, 0]}, {"x": [0, 1], "v": [2, 0]}, {"x": [0, 2], "v": [3, 0]}],
    "forces": [{"type": "nan_force", "library": ")" PINSIM_TEST_FIXTURE_DIR
         R"(/libfixture_nan_force.so", "params": {"bad": )" +
         std::to_string(bad) + R"(, "threshold": 1.0}}],
    "output": {"every": 5}
  })";
}

}  // namespace

TEST_CASE("run output: trajectory, events and summary are written") {
  const auto dir = test::temp_dir("out");
  const Scene s = parse_scene(R"({"time": {"dt": 0.01, "duration": 1.0},
    "particles": [{"x": [0, 0], "v": [1, 2]}, {"x": [1, 0]}],
    "forces": [{"type": "gravity"}], "output": {"every": 10}})",
                              "out.json", ".");
  PluginLoader loader(plugin_search_dirs());
  RunSettings rs;
  rs.out = dir;
  const RunResult r = run_scene(s, loader, rs);
  CHECK(r.exit_code == 0);
  const auto traj = lines(dir / "trajectory.csv");
  REQUIRE(traj.size() == 1 + 2 * 11);  // header + 2 particles x (t = 0, 0.1, ..., 1.0)
  CHECK(traj[0] == "t,particle,x,y,vx,vy");
  CHECK(traj[1] == "0,0,0,0,1,2");
  CHECK(lines(dir / "events.csv").size() == 1);  // header only: no obstacles
  const auto summary = nlohmann::json::parse(test::read_file(dir / "summary.json"));
  CHECK(summary["status"] == "ok");
  CHECK(summary["steps"] == 100);
  CHECK(summary["backend"] == "none");
  CHECK(summary["integrator"] == "symplectic_euler");
  CHECK(summary["energy"]["start"].get<double>() == Approx(2.5));  // 1/2 (1 + 4), E_pot(0) = 0
  CHECK(summary["versions"]["plugins"]["gravity"].is_string());
}

TEST_CASE("run output: scene.json is indented, unless indentation would dwarf it") {
  // 100 discs in a union nested 30 deep (the shape nesting limit is 32): indented, each disc's
  // ~6 lines would carry about 120 spaces each (quadratic in the depth); compact, the file is
  // about the size of its input.
  std::string shape;
  for (int i = 0; i < 100; ++i)
    shape += std::string(i ? ", " : "") + R"({"type": "circle", "center": [)" + std::to_string(i) +
             R"(, -1], "radius": 0.5})";
  shape = R"({"type": "union", "shapes": [)" + shape + "]}";
  for (int i = 0; i < 29; ++i) shape = R"({"type": "union", "shapes": [)" + shape + "]}";
  const std::string nested = R"({"time": {"dt": 0.01, "duration": 0.05},
    "particles": [{"x": [0, 0]}], "backend": {"name": "sdf"},
    "obstacles": [{"id": "w", "shape": )" +
                             shape + "}]}";
  PluginLoader loader(plugin_search_dirs());
  RunSettings rs;
  rs.out = test::temp_dir("scene-json-nested");
  REQUIRE(run_scene(parse_scene(nested, "nested.json", "."), loader, rs).exit_code == 0);
  const std::string written = test::read_file(*rs.out / "scene.json");
  CHECK(written.size() < 2 * nested.size());
  CHECK(written.find('\n') == written.size() - 1);  // one line
  CHECK(nlohmann::json::parse(written) == parse_scene(nested, "nested.json", ".").doc);

  rs.out = test::temp_dir("scene-json-flat");  // an ordinary scene stays readable
  REQUIRE(run_scene(parse_scene(R"({"time": {"dt": 0.01, "duration": 0.05},
    "particles": [{"x": [0, 0]}]})",
                                "flat.json", "."),
                    loader, rs)
              .exit_code == 0);
  CHECK_THAT(test::read_file(*rs.out / "scene.json"), Contains("{\n  \"particles\": ["));
}

TEST_CASE("run output: an earlier run is not overwritten without --overwrite") {
  const auto dir = test::temp_dir("keep");
  test::write_file(dir / "trajectory.csv", "precious\n");
  const Scene s = parse_scene(
      R"({"time": {"dt": 0.1, "duration": 0.1}, "particles": [{"x": [0, 0]}]})", "k.json", ".");
  PluginLoader loader(plugin_search_dirs());
  RunSettings rs;
  rs.out = dir;
  REQUIRE_THROWS_WITH(run_scene(s, loader, rs), Contains("holds an earlier run"));
  CHECK(test::read_file(dir / "trajectory.csv") == "precious\n");
  rs.overwrite = true;
  CHECK(run_scene(s, loader, rs).exit_code == 0);
}

TEST_CASE("run output: an unwritable output folder is an error before anything runs") {
  const auto dir = test::temp_dir("unwritable");
  test::write_file(dir / "a_file", "x");
  const Scene s = parse_scene(
      R"({"time": {"dt": 0.1, "duration": 0.1}, "particles": [{"x": [0, 0]}]})", "u.json", ".");
  PluginLoader loader(plugin_search_dirs());
  RunSettings rs;
  rs.out = dir / "a_file" / "sub";
  REQUIRE_THROWS_WITH(run_scene(s, loader, rs), Contains("cannot create output folder"));
}

TEST_CASE("NaN detection: reports the step, time, particle and plugin where it began") {
  test::FpTrapsOff traps;  // the fixture makes a NaN on purpose
  const auto dir = test::temp_dir("nan");
  PluginLoader loader(plugin_search_dirs());
  RunSettings rs;
  rs.out = dir;
  // Particle 2 moves at 3 units/s: x > 1 first after step 34 (x = 1.02), so the force at the
  // start of step 35 is the first non-finite one.
  const RunResult r = run_scene(parse_scene(nan_scene(2), "nan.json", "."), loader, rs);
  CHECK(r.exit_code == 1);
  const auto& e = r.summary["error"];
  CHECK(e["kind"] == "numeric");
  CHECK(e["numeric"] == "non_finite");
  CHECK(e["particle"] == 2);
  CHECK(e["step"] == 35);
  CHECK(e["t"].get<double>() == Approx(0.34));
  CHECK(e["plugin"] == "forces[0] 'nan_force'");
  CHECK_THAT(e["message"].get<std::string>(),
             StartsWith("non-finite force (nan, 0) on particle 2 from forces[0] 'nan_force' at "
                        "x = (1.02, 2), v = (3, 0)"));
  // What was written before the failure is intact: complete lines, a valid summary.
  const auto summary = nlohmann::json::parse(test::read_file(dir / "summary.json"));
  CHECK(summary["status"] == "error");
  CHECK(summary["steps"] == 34);
  const auto traj = lines(dir / "trajectory.csv");
  CHECK(traj.size() == 1 + 3 * 7);  // t = 0, 0.05, ..., 0.30
  for (const auto& l : traj) CHECK(std::count(l.begin(), l.end(), ',') == 5);
}

TEST_CASE("energy blow-up detection stops the run where it began") {
  // Two unit masses on a zero-rest-length spring: reduced mass mu = 1/2, omega = sqrt(k/mu).
  // Symplectic Euler is stable for h omega < 2. k = 1e4: omega = 141.4; h = 0.01 gives
  // h omega = 1.41 (stable), h = 0.02 gives 2.83, where the amplification factor is
  // |lambda| = (y^2 - 2 + sqrt((y^2 - 2)^2 - 4)) / 2 = 5.83 per step, y = h omega.
  auto scene = [](double h) {
    return R"({"time": {"dt": )" + std::to_string(h) + R"(, "duration": 2.0},
      "particles": [{"x": [0, 0]}, {"x": [0.1, 0], "v": [0, 0.5]}],
      "forces": [{"type": "linear_spring", "params": {"k": 1e4, "rest_length": 0},
                  "elements": [[0, 1]]}],
      "checks": {"energy_blowup": 1000, "energy_every": 1}})";
  };
  PluginLoader loader(plugin_search_dirs());
  const RunResult ok = run_scene(parse_scene(scene(0.01), "stable.json", "."), loader, {});
  CHECK(ok.exit_code == 0);
  // Below the limit symplectic Euler's energy oscillates (here up to about 2x the scale, as
  // y^2/4 = 0.5) but stays bounded over 200 steps.
  CHECK(ok.summary["energy"]["max_relative_drift"].get<double>() < 3.0);

  test::FpTrapsOff traps;
  const RunResult bad = run_scene(parse_scene(scene(0.02), "unstable.json", "."), loader, {});
  CHECK(bad.exit_code == 1);
  const auto& e = bad.summary["error"];
  CHECK(e["kind"] == "numeric");
  CHECK(e["numeric"] == "energy_blowup");
  CHECK_THAT(e["message"].get<std::string>(), Contains("energy blow-up"));
  // Energy grows by about 5.83^2 = 34 per step: past 1000 x the start within a few steps.
  CHECK(e["step"].get<int>() <= 4);
  CHECK(e["particle"].get<int>() >= 0);
}

TEST_CASE("implicit Euler reports its linear solves in summary.json") {
  // A hanging chain of 8 damped springs: each step is one linear solve.
  const std::string scene = R"({"time": {"dt": 0.01, "duration": 0.5},
    "integrator": "implicit_euler",
    "bodies": [{"name": "chain", "type": "strand", "root": [0, 0], "direction": [1, 0],
                "count": 9, "segment_length": 0.1, "mass": 0.1}],
    "forces": [{"type": "gravity"},
               {"type": "damped_spring", "params": {"ks": 500, "kd": 0.5},
                "elements": {"body": "chain", "set": "edges"}}]})";
  PluginLoader loader(plugin_search_dirs());
  const RunResult r = run_scene(parse_scene(scene, "chain.json", "."), loader, {});
  REQUIRE(r.exit_code == 0);
  const auto& solver = r.summary["solver"];
  CHECK(solver["linear_solves"] == 50);
  CHECK(solver["cg_iterations_per_solve"].get<double>() > 0);
  CHECK(solver["cg_iterations_max"].get<int>() >= 1);
  CHECK(solver["lu_fallbacks"] == 0);
  // CG stops at a relative residual of 1e-12 (its tolerance).
  CHECK(solver["worst_relative_residual"].get<double>() <= 1e-12);
  // Explicit integrators have no solver figures.
  const RunResult e =
      run_scene(parse_scene(scene, "chain.json", ".", {"integrator=symplectic_euler"}), loader, {});
  CHECK_FALSE(e.summary.contains("solver"));
}

TEST_CASE("implicit Euler: a failed linear solve stops the run as a solver failure") {
  // The fixture's Jacobian is NaN: conjugate gradients and sparse LU both fail, and the
  // step must not go on with an unconverged velocity.
  test::FpTrapsOff traps;
  const std::string scene = R"({"time": {"dt": 0.01, "duration": 0.1},
    "integrator": "implicit_euler",
    "particles": [{"x": [0, 0]}, {"x": [1, 0]}],
    "forces": [{"type": "nan_jacobian", "library": ")" PINSIM_TEST_FIXTURE_DIR
                            R"(/libfixture_nan_jacobian.so", "elements": [[0, 1]]}]})";
  PluginLoader loader(plugin_search_dirs());
  const RunResult r = run_scene(parse_scene(scene, "nan_jacobian.json", "."), loader, {});
  CHECK(r.exit_code == 1);
  const auto& e = r.summary["error"];
  CHECK(e["kind"] == "numeric");
  CHECK(e["numeric"] == "solver_failure");
  CHECK(e["step"] == 1);
  CHECK_THAT(e["message"].get<std::string>(), Contains("implicit_euler: the linear solve failed"));
}

TEST_CASE("a plugin's Jacobian entry outside the state stops the run naming the plugin") {
  // The fixture's df/dx adds one entry past the last degree of freedom (kind 0: row 2n) or
  // one 2x2 block at particle n (kind 1). Implicit Euler must neither read nor write past
  // its arrays (under ASan it would be reported) but stop at the first step, naming the
  // plugin, the entry and the bounds.
  for (const int kind : {0, 1}) {
    CAPTURE(kind);
    const std::string scene = R"({"time": {"dt": 0.01, "duration": 0.1},
      "integrator": "implicit_euler",
      "particles": [{"x": [0, 0]}, {"x": [1, 0]}],
      "forces": [{"type": "bad_jacobian_index", "library": ")" PINSIM_TEST_FIXTURE_DIR
                              R"(/libfixture_bad_jacobian_index.so", "elements": [[0, 1]],
                  "params": {"kind": )" +
                              std::to_string(kind) + "}}]}";
    PluginLoader loader(plugin_search_dirs());
    const RunResult r = run_scene(parse_scene(scene, "bad_index.json", "."), loader, {});
    CHECK(r.exit_code == 1);
    const auto& e = r.summary["error"];
    CHECK(e["kind"] == "plugin");
    CHECK(e["step"] == 1);
    const std::string m = e["message"].get<std::string>();
    CHECK_THAT(m, Contains("forces[0]: plugin 'bad_jacobian_index' add_jacobians: its df/dx has"));
    CHECK_THAT(
        m, Contains(kind == 0 ? "an entry at row 4, column 0" : "a 2x2 block at particles (2, 0)"));
    CHECK_THAT(m, Contains("rows and columns must be below 4, block particles below 2"));
  }
}

TEST_CASE("interrupted run: stops cleanly with valid files") {
  const auto dir = test::temp_dir("interrupt");
  std::atomic<int> stop{SIGINT};
  const Scene s = parse_scene(R"({"time": {"dt": 0.1, "duration": 10},
    "particles": [{"x": [0, 0]}]})",
                              "i.json", ".");
  PluginLoader loader(plugin_search_dirs());
  RunSettings rs;
  rs.out = dir;
  rs.stop = &stop;
  const RunResult r = run_scene(s, loader, rs);
  CHECK(r.exit_code == 130);
  const auto summary = nlohmann::json::parse(test::read_file(dir / "summary.json"));
  CHECK(summary["status"] == "interrupted");
  CHECK(summary["signal"] == nlohmann::json{{"name", "SIGINT"}, {"number", 2}});
  CHECK(summary["steps"] == 0);
  CHECK(lines(dir / "trajectory.csv").size() == 2);  // header + the initial state
}

namespace {
// A ball on a spring to a pinned anchor, a damped spring beside it (kd 0.2) and a box of
// restitution 0.5 around them: nothing adds energy, so the total can only fall (up to the
// integrator's error). `spring`: the linear spring, or the wrong_sign fixture (its force
// flipped, its energy the right one): the rest length is then unstable, the ball runs away
// as exp(sqrt(k/m) t) and the energy rises.
std::string spring_scene(const std::string& spring, const std::string& extra = "") {
  const std::string lib = spring == "wrong_sign" ? R"(, "library": ")" PINSIM_TEST_FIXTURE_DIR
                                                   R"(/libfixture_wrong_sign.so")"
                                                 : "";
  const std::string params =
      spring == "wrong_sign" ? R"({"k": 10})" : R"({"k": 10, "rest_length": 1})";
  return R"({"time": {"dt": 0.001, "duration": 1.0}, "backend": {"name": "sdf"},
    "particles": [{"x": [0, 0], "pinned": true}, {"x": [1, 0], "v": [0.5, 0.3], "radius": 0.05}],
    "forces": [{"type": ")" +
         spring + "\"" + lib + R"(, "params": )" + params + R"(, "elements": [[0, 1]]},
               {"type": "damped_spring", "params": {"ks": 1, "kd": 0.2}, "elements": [[0, 1]]}],
    "obstacles": [{"id": "box", "shape": {"type": "inside", "shape": {"type": "box",
      "center": [0, 0], "half_size": [3, 3]}}, "material": {"restitution": 0.5)" +
         extra + R"(}}], "output": {"every": 100}})";
}
}  // namespace

TEST_CASE("run output: an energy rise with nothing that adds energy warns in the summary") {
  PluginLoader loader(plugin_search_dirs());
  RunSettings rs;
  const RunResult bad =
      run_scene(parse_scene(spring_scene("wrong_sign"), "s.json", "."), loader, rs);
  CHECK(bad.exit_code == 0);  // a warning, not a failure
  CHECK(bad.summary["status"] == "ok");
  REQUIRE(bad.summary.contains("warnings"));
  REQUIRE(bad.summary["warnings"].size() == 1);
  CHECK(bad.summary["warnings"][0]["kind"] == "energy_rise");
  CHECK_THAT(bad.summary["warnings"][0]["message"].get<std::string>(),
             Catch::Matchers::Contains("the total energy rose from"));
  const double e0 = bad.summary["energy"]["start"], e1 = bad.summary["energy"]["end"];
  CHECK(e1 > (1 + kEnergyRiseBound) * e0);
  // Written to summary.json too.
  const auto dir = test::temp_dir("energy_rise");
  rs.out = dir;
  run_scene(parse_scene(spring_scene("wrong_sign"), "s.json", "."), loader, rs);
  const auto on_disk = nlohmann::json::parse(test::read_file(dir / "summary.json"));
  CHECK(on_disk["warnings"][0]["kind"] == "energy_rise");
  rs.out.reset();

  // The right spring: the energy falls (damping, restitution 0.5), no warning.
  const RunResult good =
      run_scene(parse_scene(spring_scene("linear_spring"), "s.json", "."), loader, rs);
  CHECK(good.summary["energy"]["end"].get<double>() <
        good.summary["energy"]["start"].get<double>());
  CHECK_FALSE(good.summary.contains("warnings"));
  // With a kicking obstacle something may add energy: the same rise is not a warning.
  const RunResult kicked = run_scene(
      parse_scene(spring_scene("wrong_sign", R"(, "kick": 1)"), "s.json", "."), loader, rs);
  CHECK(kicked.summary["energy"]["end"].get<double>() > (1 + kEnergyRiseBound) * e0);
  CHECK_FALSE(kicked.summary.contains("warnings"));
}
