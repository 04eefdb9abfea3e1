// `pinsim grad` and `pinsim fit` through the command line: gradient.json, the same run as
// `pinsim run`, bad input as exit 2 naming it, and fits recovering the values of a recorded
// run.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "test_support.hpp"
#include "whole_runs.hpp"

using namespace pinsim;

namespace {

nlohmann::json read_json(const std::filesystem::path& p) {
  return nlohmann::json::parse(test::read_file(p));
}

const std::string kProjectile = PINSIM_SOURCE_DIR "/configs/projectile.json";

}  // namespace

TEST_CASE("grad cli: gradient.json, and the run is the one pinsim run makes", "[gradients][cli]") {
  const auto dir = test::temp_dir("grad_cli");
  const std::string scene = PINSIM_SOURCE_DIR "/configs/two_mass_oscillator.json";
  const std::string set = " --set time.duration=0.3 'particles[1].v=[0.1,0.2]'";
  const auto g = test::pinsim_cli("grad " + scene + set +
                                  " --loss final:1:x --wrt 'particles[1].v' "
                                  "'forces[0].params.k' --out " +
                                  (dir / "g").string());
  INFO(g.output);
  REQUIRE(g.code == 0);
  const auto r = test::pinsim_cli("run " + scene + set + " --out " + (dir / "r").string());
  REQUIRE(r.code == 0);
  const nlohmann::json j = read_json(dir / "g" / "gradient.json");
  const nlohmann::json s = read_json(dir / "r" / "summary.json");
  CHECK(j["state_hash"] == s["state_hash"]);
  CHECK(j["steps"] == 600);
  CHECK(j["paths"]["particles[1].v"]["gradient"].size() == 2);
  CHECK(j["paths"]["particles[1].v"]["value"] == nlohmann::json::array({0.1, 0.2}));
  CHECK(j["paths"]["forces[0].params.k"]["gradient"].size() == 1);
  // linear_spring gives d f / d k itself (ABI 4.4 add_dforce_dparam)
  CHECK(j["paths"]["forces[0].params.k"]["parameter derivative"] == "plugin");
  CHECK(j["parameter derivative"]["method"] == "plugin");
  CHECK(j["differentiable"] == true);
  CHECK(j["cost"]["forward_s"].get<double>() > 0.0);
  CHECK(j["cost"]["backward_s"].get<double>() > 0.0);
  CHECK(j["cost"]["forward_force_evaluations"] == 1200);  // velocity Verlet: 2 a step
  CHECK(j["replay_deviation"] == 0.0);
  // the loss is the final x of the run pinsim run wrote: its last trajectory row
  const std::string traj = test::read_file(dir / "r" / "trajectory.csv");
  const auto last = traj.rfind('\n', traj.size() - 2);
  const std::string row = traj.substr(last + 1);
  CHECK(row.rfind("0.3,1,", 0) == 0);
  const double x = std::stod(row.substr(6));
  CHECK(j["loss"].get<double>() == x);
}

TEST_CASE("grad cli: --parameter-derivative differences, to cross-check a plugin's",
          "[gradients][cli]") {
  const auto dir = test::temp_dir("grad_cli_fd");
  const std::string scene = PINSIM_SOURCE_DIR "/configs/two_mass_oscillator.json";
  const std::string common = "grad " + scene +
                             " --set time.duration=0.3 --loss final:1:x --wrt "
                             "'forces[0].params.k' --out ";
  const auto p = test::pinsim_cli(common + (dir / "p").string());
  const auto d =
      test::pinsim_cli(common + (dir / "d").string() + " --parameter-derivative differences");
  INFO(p.output << d.output);
  REQUIRE(p.code == 0);
  REQUIRE(d.code == 0);
  const nlohmann::json jp = read_json(dir / "p" / "gradient.json");
  const nlohmann::json jd = read_json(dir / "d" / "gradient.json");
  CHECK(jd["paths"]["forces[0].params.k"]["parameter derivative"] == "finite differences");
  CHECK(jd["parameter derivative"]["relative_step"] == 1e-6);
  const double gp = jp["paths"]["forces[0].params.k"]["gradient"][0].get<double>();
  const double gd = jd["paths"]["forces[0].params.k"]["gradient"][0].get<double>();
  CHECK(gp == Approx(gd).epsilon(1e-7));
  const auto bad =
      test::pinsim_cli(common + (dir / "b").string() + " --parameter-derivative exact");
  CHECK(bad.code != 0);
  CHECK(bad.output.find("--parameter-derivative") != std::string::npos);
}

TEST_CASE("grad cli: the misfit to a recorded run folder", "[gradients][cli]") {
  const auto dir = test::temp_dir("grad_misfit");
  const std::string scene = PINSIM_SOURCE_DIR "/configs/two_mass_oscillator.json";
  REQUIRE(
      test::pinsim_cli("run " + scene + " --set time.duration=0.2 --out " + (dir / "rec").string())
          .code == 0);
  // the same scene: misfit 0 and gradient 0 at the recorded values
  const auto same = test::pinsim_cli(
      "grad " + scene + " --set time.duration=0.2 --loss misfit:" + (dir / "rec").string() +
      " --wrt 'forces[0].params.k' --out " + (dir / "a").string());
  INFO(same.output);
  REQUIRE(same.code == 0);
  const nlohmann::json a = read_json(dir / "a" / "gradient.json");
  CHECK(a["loss"] == 0.0);
  CHECK(a["paths"]["forces[0].params.k"]["gradient"][0] == 0.0);
  // a stiffer spring: a positive misfit that grows with k
  const auto stiff = test::pinsim_cli(
      "grad " + scene + " --set time.duration=0.2 'forces[0].params.k=55' --loss misfit:" +
      (dir / "rec").string() + " --wrt 'forces[0].params.k' --out " + (dir / "b").string());
  REQUIRE(stiff.code == 0);
  const nlohmann::json b = read_json(dir / "b" / "gradient.json");
  CHECK(b["loss"].get<double>() > 0.0);
  CHECK(b["paths"]["forces[0].params.k"]["gradient"][0].get<double>() > 0.0);
}

TEST_CASE("grad cli: bad input is exit 2 naming it", "[gradients][cli]") {
  const auto unknown =
      test::pinsim_cli("grad " + kProjectile + " --loss final:0:x --wrt 'particles[4].v'");
  CHECK(unknown.code == 2);
  CHECK_THAT(unknown.output, Catch::Contains("--wrt particles[4].v"));
  const auto not_diff =
      test::pinsim_cli("grad " + kProjectile + " --loss final:0:x --wrt time.duration");
  CHECK(not_diff.code == 2);
  CHECK_THAT(not_diff.output, Catch::Contains("--wrt time.duration: not differentiable"));
  const auto loss =
      test::pinsim_cli("grad " + kProjectile + " --loss speed:0 --wrt 'particles[0].v'");
  CHECK(loss.code == 2);
  CHECK_THAT(loss.output, Catch::Contains("--loss speed:0") && Catch::Contains("unknown kind"));
  const auto misfit = test::pinsim_cli("grad " + kProjectile +
                                       " --loss misfit:/nonexistent --wrt 'particles[0].v'");
  CHECK(misfit.code == 2);
  CHECK_THAT(misfit.output, Catch::Contains("/nonexistent"));
  const auto box2d = test::pinsim_cli(
      "grad " + kProjectile +
      " --set 'backend={\"name\":\"box2d\"}' --loss final:0:x --wrt 'particles[0].v'");
  CHECK(box2d.code == 2);
  CHECK_THAT(box2d.output, Catch::Contains("backend 'box2d' cannot differentiate its step"));
}

TEST_CASE("fit cli: a blob's ks and kd recovered from its own recorded run",
          "[gradients][cli][fit]") {
  const auto dir = test::temp_dir("fit_blob");
  test::write_file(dir / "blob.json", grad::testing::kFlyingBlob);
  const std::string scene = (dir / "blob.json").string();
  REQUIRE(test::pinsim_cli("run " + scene + " -q --out " + (dir / "rec").string()).code == 0);
  const auto fit = test::pinsim_cli(
      "fit " + scene + " --set 'forces[1].params.ks=200' 'forces[1].params.kd=0.8' --target " +
      (dir / "rec").string() + " --wrt 'forces[1].params.ks' 'forces[1].params.kd' --out " +
      (dir / "fit").string());
  INFO(fit.output);
  REQUIRE(fit.code == 0);
  CHECK_THAT(fit.output, Catch::Contains("iteration 0 (1 runs): misfit") &&
                             Catch::Contains("iteration 1 (") && Catch::Contains("fitted ("));
  const nlohmann::json j = read_json(dir / "fit" / "fit.json");
  CHECK(j["values"]["forces[1].params.ks"].get<double>() == Approx(300.0).epsilon(1e-6));
  CHECK(j["values"]["forces[1].params.kd"].get<double>() == Approx(0.4).epsilon(1e-6));
  CHECK(j["history"].size() == j["iterations"].get<std::size_t>() + 1);
  // the fitted scene holds the values and runs
  const nlohmann::json fitted = read_json(dir / "fit" / "scene.json");
  CHECK(fitted["forces"][1]["params"]["ks"] == j["values"]["forces[1].params.ks"]);
  CHECK(test::pinsim_cli("run " + (dir / "fit" / "scene.json").string() + " -q").code == 0);
}

// The same blob thrown from elsewhere: its launch point and velocity recovered from the
// recorded flight (the misfit is quadratic in both for a blob in free fall, whose springs see
// neither; see the closed forms in test_scene_gradient.cpp).
TEST_CASE("fit cli: a blob's launch point and velocity recovered from its recorded run",
          "[gradients][cli][fit]") {
  const auto dir = test::temp_dir("fit_blob_launch");
  test::write_file(dir / "blob.json", grad::testing::kFlyingBlob);
  const std::string scene = (dir / "blob.json").string();
  REQUIRE(test::pinsim_cli("run " + scene + " -q --out " + (dir / "rec").string()).code == 0);
  const auto fit = test::pinsim_cli(
      "fit " + scene + " --set 'bodies[0].center=[0.2,0.7]' 'bodies[0].velocity=[-0.5,1.5]'" +
      " --target " + (dir / "rec").string() +
      " --wrt 'bodies[0].center' 'bodies[0].velocity' --out " + (dir / "fit").string());
  INFO(fit.output);
  REQUIRE(fit.code == 0);
  const nlohmann::json j = read_json(dir / "fit" / "fit.json");
  CHECK(j["values"]["bodies[0].center[0]"].get<double>() == Approx(0.0).margin(1e-6));
  CHECK(j["values"]["bodies[0].center[1]"].get<double>() == Approx(1.0).epsilon(1e-6));
  CHECK(j["values"]["bodies[0].velocity[0]"].get<double>() == Approx(0.4).epsilon(1e-6));
  CHECK(j["values"]["bodies[0].velocity[1]"].get<double>() == Approx(0.3).epsilon(1e-6));
  const nlohmann::json fitted = read_json(dir / "fit" / "scene.json");
  CHECK(fitted["bodies"][0]["velocity"][0] == j["values"]["bodies[0].velocity[0]"]);
}

TEST_CASE("fit cli: bad input is exit 2 naming it", "[gradients][cli][fit]") {
  const auto no_run =
      test::pinsim_cli("fit " + kProjectile + " --target /nonexistent --wrt 'particles[0].v'");
  CHECK(no_run.code == 2);
  CHECK_THAT(no_run.output, Catch::Contains("/nonexistent"));
  const auto path = test::pinsim_cli("fit " + kProjectile +
                                     " --target /nonexistent --wrt 'forces[0].params.mode'");
  CHECK(path.code == 2);
  CHECK_THAT(path.output, Catch::Contains("--wrt forces[0].params.mode: not differentiable"));
}

TEST_CASE("grad cli: pinsim plugins shows which backends differentiate their step",
          "[gradients][cli]") {
  const auto none = test::pinsim_cli("plugins none");
  REQUIRE(none.code == 0);
  CHECK_THAT(none.output, Catch::Contains("differentiable"));
  const auto sdf = test::pinsim_cli("plugins sdf");
  REQUIRE(sdf.code == 0);
  CHECK_THAT(sdf.output, Catch::Contains("differentiable"));
  const auto box2d = test::pinsim_cli("plugins box2d");
  REQUIRE(box2d.code == 0);
  CHECK_THAT(box2d.output, !Catch::Contains("differentiable"));
}

TEST_CASE("fit cli: a table's restitution recovered from a recorded bounce",
          "[gradients][cli][fit]") {
  const auto dir = test::temp_dir("fit_bounce");
  test::write_file(dir / "bounce.json", R"({
    "time": {"dt": 0.005, "duration": 1.0},
    "backend": {"name": "sdf"},
    "particles": [{"x": [0.0, 0.6], "v": [0.3, 0.0], "mass": 1.0, "radius": 0.05}],
    "forces": [{"type": "gravity", "params": {"g": [0.0, -9.81]}}],
    "obstacles": [{"id": "table", "shape": {"type": "half_plane", "point": [0, 0],
                   "normal": [0, 1]}, "material": {"restitution": 0.75}}],
    "output": {"every": 10}
  })");
  const std::string scene = (dir / "bounce.json").string();
  REQUIRE(test::pinsim_cli("run " + scene + " -q --out " + (dir / "rec").string()).code == 0);
  const auto fit = test::pinsim_cli(
      "fit " + scene + " --set 'obstacles[0].material.restitution=0.5' --target " +
      (dir / "rec").string() + " --wrt 'obstacles[0].material.restitution' --out " +
      (dir / "fit").string());
  INFO(fit.output);
  REQUIRE(fit.code == 0);
  const nlohmann::json j = read_json(dir / "fit" / "fit.json");
  CHECK(j["values"]["obstacles[0].material.restitution"].get<double>() ==
        Approx(0.75).epsilon(1e-6));
  CHECK(j["misfit"].get<double>() < 1e-12);
}

TEST_CASE("fit cli: a launch velocity that reaches a target after two obstacles",
          "[gradients][cli][fit]") {
  // The ball off a box and a circle (test_sdf_gradient.cpp's scene); the target is where the
  // launch (2, 2.5) ends, the fit starts from (2.05, 2.45). Velocity Verlet: with symplectic
  // Euler the run jumps where a time of impact crosses a step boundary (the kick of the step
  // comes before or after the impulse: a velocity jump (1 + e) h (g.n) n), and the line
  // search stalls at such a jump on the way (docs/gradients.md).
  const auto dir = test::temp_dir("fit_launch");
  test::write_file(dir / "launch.json", R"({
    "time": {"dt": 0.002, "duration": 0.6},
    "integrator": "velocity_verlet",
    "backend": {"name": "sdf"},
    "particles": [{"x": [0.0, 0.3], "v": [2.0, 2.5], "mass": 1.0, "radius": 0.05}],
    "forces": [{"type": "gravity", "params": {"g": [0.0, -9.81]}}],
    "obstacles": [
      {"id": "post", "shape": {"type": "circle", "center": [0.6, 0.1], "radius": 0.15},
       "material": {"restitution": 0.9}},
      {"id": "block", "shape": {"type": "box", "center": [0.35, 0.65], "half_size": [0.25, 0.05]},
       "material": {"restitution": 0.7}},
      {"id": "floor", "shape": {"type": "half_plane", "point": [0, -0.5], "normal": [0, 1]},
       "material": {"restitution": 0.6}}
    ]
  })");
  const std::string scene = (dir / "launch.json").string();
  const auto run = test::pinsim_cli("run " + scene + " -q --out " + (dir / "rec").string());
  REQUIRE(run.code == 0);
  // the last row of trajectory.csv (t,particle,x,y,vx,vy): the final state
  const std::string traj = test::read_file(dir / "rec" / "trajectory.csv");
  const std::string last = traj.substr(traj.rfind('\n', traj.size() - 2) + 1);
  INFO(last);
  REQUIRE(last.rfind("0.6,0,", 0) == 0);
  double X = 0.0, Y = 0.0;
  REQUIRE(std::sscanf(last.c_str(), "%*[^,],%*[^,],%lf,%lf", &X, &Y) == 2);
  char target[80];
  std::snprintf(target, sizeof target, "target:0:%.17g,%.17g", X, Y);
  const auto fit =
      test::pinsim_cli("fit " + scene + " --set 'particles[0].v=[2.05,2.45]' --loss " + target +
                       " --wrt 'particles[0].v' --out " + (dir / "fit").string());
  INFO(fit.output);
  REQUIRE(fit.code == 0);
  const nlohmann::json j = read_json(dir / "fit" / "fit.json");
  CHECK(j["misfit"].get<double>() < 1e-12);
  // the fitted launch bounces off the circle and the box on its way
  const auto check = test::pinsim_cli("run " + (dir / "fit" / "scene.json").string() +
                                      " -q --out " + (dir / "check").string());
  REQUIRE(check.code == 0);
  const std::string events = test::read_file(dir / "check" / "events.csv");
  CHECK_THAT(events, Catch::Contains(",0,post,") && Catch::Contains(",0,block,"));
}
