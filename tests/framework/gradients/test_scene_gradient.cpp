// The gradient of a whole run of a scene with its plugins (scene_gradient, `pinsim grad`):
// against central differences of whole runs with --set, and closed forms.
#include <catch2/catch.hpp>
#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>

#include "core/input_error.hpp"
#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "gradients/scene_gradient.hpp"
#include "test_support.hpp"

using namespace pinsim;
using namespace pinsim::grad;

namespace {

std::string text(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

/// A scene file written from `json` into a fresh folder.
std::string scene_file(const std::string& tag, const std::string& json) {
  const auto dir = test::temp_dir(tag);
  test::write_file(dir / "scene.json", json);
  return (dir / "scene.json").string();
}

/// The loss of a whole run of `file` with `overrides`: the run `pinsim run --set` makes
/// (Simulation::step, scene.steps() times), the loss summed over its step ends.
double run_loss(const std::string& file, const std::vector<std::string>& overrides,
                const std::string& loss_spec, const std::string& integrator) {
  const Scene scene = load_scene(file, overrides);
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  RunOptions opt;
  opt.integrator = integrator;
  opt.threads = 1;
  Simulation sim(scene, loader, opt);
  const auto loss = parse_loss(loss_spec, {scene.steps(), scene.dt, sim.state().size()});
  Eigen::Matrix2Xd gx = Eigen::Matrix2Xd::Zero(2, static_cast<Eigen::Index>(sim.state().size()));
  Eigen::Matrix2Xd gv = gx;
  double l = loss->has_term(0) ? loss->term(0, sim.state(), gx, gv) : 0.0;
  for (uint64_t n = 1; n <= scene.steps(); ++n) {
    sim.step();
    if (loss->has_term(n)) l += loss->term(n, sim.state(), gx, gv);
  }
  return l;
}

GradientReport gradient(const std::string& file, const std::vector<std::string>& overrides,
                        const std::string& loss_spec, const std::vector<std::string>& wrt,
                        const std::string& integrator, uint64_t segment = 0) {
  const Scene scene = load_scene(file, overrides);
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  GradientOptions opt;
  opt.run.integrator = integrator;
  opt.run.threads = 1;
  opt.segment = segment;
  return scene_gradient(
      scene, loader, wrt, [&](const LossContext& c) { return parse_loss(loss_spec, c); }, opt);
}

/// The assignment of a value's components with component c moved by d.
std::string moved(const WrtValue& w, std::size_t c, double d) {
  if (w.value.size() == 1) return w.path + "=" + text(w.value[0] + d);
  std::vector<double> v = w.value;
  v[c] += d;
  return w.path + "=[" + text(v[0]) + "," + text(v[1]) + "]";
}

/// Every component of every --wrt value against the central difference of whole runs,
///   dL/dtheta ~ (L(theta + e) - L(theta - e)) / (2 e),  e = 1e-4 max(|theta|, 1)
/// (truncation O(e^2 L'''/L'), about 1e-8 relative here; rounding O(1e-16 L / e)).
void check_against_runs(const std::string& file, const std::vector<std::string>& overrides,
                        const std::string& loss, const std::vector<std::string>& wrt,
                        const std::string& integrator, double rel = 1e-6) {
  const GradientReport r = gradient(file, overrides, loss, wrt, integrator);
  REQUIRE(r.paths.size() == wrt.size());
  CHECK(r.loss == Approx(run_loss(file, overrides, loss, integrator)).epsilon(1e-14));
  for (const PathGradient& p : r.paths)
    for (std::size_t c = 0; c < p.wrt.value.size(); ++c) {
      const double e = 1e-4 * std::max(std::abs(p.wrt.value[c]), 1.0);
      std::vector<std::string> up = overrides, down = overrides;
      up.push_back(moved(p.wrt, c, e));
      down.push_back(moved(p.wrt, c, -e));
      const double fd =
          (run_loss(file, up, loss, integrator) - run_loss(file, down, loss, integrator)) /
          (2.0 * e);
      const double g = p.gradient[static_cast<Eigen::Index>(c)];
      INFO(file << " " << integrator << " " << p.wrt.path << "[" << c << "]: adjoint " << g
                << ", runs " << fd);
      CHECK(std::isfinite(g));
      CHECK(std::abs(g - fd) <= rel * std::max(std::abs(fd), 1e-3 * std::abs(r.loss)));
    }
}

// A ring blob of damped springs under gravity, no obstacles (backend none).
const char* kBlob = R"({
  "time": {"dt": 0.001, "duration": 0.3},
  "backend": {"name": "none"},
  "bodies": [{"type": "ring_blob", "name": "blob", "center": [0.0, 1.0], "ring_radius": 0.3,
              "count": 8, "total_mass": 0.8, "radius": 0.02, "velocity": [0.4, 0.3]}],
  "forces": [
    {"type": "gravity", "params": {"g": [0.0, -9.81]}},
    {"type": "damped_spring", "params": {"ks": 300.0, "kd": 0.4, "rest_length": 0.25},
     "elements": {"body": "blob", "set": "edges"}},
    {"type": "damped_spring", "params": {"ks": 100.0, "kd": 0.2, "rest_length": 0.55},
     "elements": {"body": "blob", "set": "cross"}}
  ]
})";

// Two particles on a damped spring whose rest length comes from their initial distance.
const char* kPair = R"({
  "time": {"dt": 0.001, "duration": 0.5},
  "backend": {"name": "none"},
  "particles": [
    {"x": [0.0, 0.0], "v": [0.0, 0.5], "mass": 1.0, "radius": 0.05},
    {"x": [0.9, 0.1], "v": [0.3, 0.0], "mass": 2.0, "radius": 0.05}
  ],
  "forces": [
    {"type": "damped_spring", "params": {"ks": 40.0, "kd": 0.3}, "elements": [[0, 1]]}
  ]
})";

}  // namespace

TEST_CASE("scene gradient: springs against whole runs, three integrators", "[gradients][scene]") {
  const std::string file = PINSIM_SOURCE_DIR "/configs/two_mass_oscillator.json";
  const std::vector<std::string> set{"time.duration=0.5", "particles[1].v=[0.2,0.1]"};
  for (const char* integrator : {"symplectic_euler", "velocity_verlet", "implicit_euler"})
    check_against_runs(
        file, set, "final:1:x",
        {"particles[1].v", "particles[0].x", "forces[0].params.k", "forces[0].params.rest_length"},
        integrator);
}

TEST_CASE("scene gradient: a blob's stiffness, damping and gravity against whole runs",
          "[gradients][scene]") {
  const std::string file = scene_file("grad_blob", kBlob);
  for (const char* integrator : {"symplectic_euler", "velocity_verlet", "implicit_euler"})
    check_against_runs(
        file, {}, "target:3:0.2,0.8@0.2",
        {"forces[1].params.ks", "forces[1].params.kd", "forces[2].params.ks", "forces[0].params.g"},
        integrator);
}

TEST_CASE("scene gradient: a hair strand's bending and stretch against whole runs",
          "[gradients][scene]") {
  const std::string file = PINSIM_SOURCE_DIR "/configs/hair_strand.json";
  check_against_runs(file, {"time.duration=0.04"}, "final:11:y",
                     {"forces[2].params.k", "forces[1].params.ks", "forces[1].params.kd"},
                     "symplectic_euler");
}

TEST_CASE("scene gradient: initial positions through the rest lengths they set",
          "[gradients][scene]") {
  const std::string file = scene_file("grad_pair", kPair);
  for (const char* integrator : {"symplectic_euler", "velocity_verlet", "implicit_euler"})
    check_against_runs(file, {}, "final:1:y", {"particles[1].x", "particles[0].v"}, integrator);
}

// Symplectic Euler under uniform gravity: v_n = v0 + n h g, x_N = x0 + h sum_{n=1..N} v_n
//   = x0 + v0 T + g h^2 N (N + 1) / 2, so d x(T) / d v0 = T and d y(T) / d g_y = T (T + h) / 2
// exactly, for any step (T = N h).
TEST_CASE("scene gradient: projectile closed forms", "[gradients][scene]") {
  const std::string file = PINSIM_SOURCE_DIR "/configs/projectile.json";
  const GradientReport r = gradient(file, {}, "final:0:x", {"particles[0].v"}, "");
  REQUIRE(r.paths.size() == 1);
  CHECK(r.paths[0].gradient[0] == Approx(1.0).epsilon(1e-12));
  CHECK(r.paths[0].gradient[1] == 0.0);
  const GradientReport g = gradient(file, {}, "final:0:y", {"forces[0].params.g"}, "");
  const double T = 1.0, h = 0.001;
  CHECK(g.paths[0].gradient[0] == 0.0);
  CHECK(g.paths[0].gradient[1] == Approx(T * (T + h) / 2.0).epsilon(1e-9));
  CHECK(g.steps == 1000);
  CHECK(g.segment == 32);
  CHECK(g.checkpoints == 32);
}

// One mass on a damped spring to a pinned anchor along x: m u'' + kd u' + ks u = 0 for the
// stretch u = x - L, u(0) = u0, u'(0) = 0 (underdamped):
//   u(t) = e^(-g t) (u0 cos(w t) + (g u0 / w) sin(w t)),  g = kd / (2 m),
//   w = sqrt(ks / m - g^2).
// The reference derivatives are central differences of this closed form in ks and kd; the run
// (velocity Verlet, second order) approaches it as h^2.
TEST_CASE("scene gradient: a damped spring's final position in ks and kd, closed form",
          "[gradients][scene]") {
  const double m = 2.0, ks = 30.0, kd = 0.8, L = 1.0, u0 = 0.2, T = 1.3;
  const std::string file = scene_file("grad_damped", R"({
    "time": {"dt": 0.0001, "duration": 1.3},
    "integrator": "velocity_verlet",
    "backend": {"name": "none"},
    "particles": [
      {"x": [0.0, 0.0], "v": [0.0, 0.0], "mass": 1.0, "radius": 0.05, "pinned": true},
      {"x": [1.2, 0.0], "v": [0.0, 0.0], "mass": 2.0, "radius": 0.05}
    ],
    "forces": [{"type": "damped_spring", "params": {"ks": 30.0, "kd": 0.8, "rest_length": 1.0},
                "elements": [[0, 1]]}]
  })");
  auto x_T = [&](double k, double c) {
    const double g = c / (2.0 * m), w = std::sqrt(k / m - g * g);
    return L + std::exp(-g * T) * (u0 * std::cos(w * T) + (g * u0 / w) * std::sin(w * T));
  };
  const double e = 1e-6;
  const double dks = (x_T(ks + e, kd) - x_T(ks - e, kd)) / (2 * e);
  const double dkd = (x_T(ks, kd + e) - x_T(ks, kd - e)) / (2 * e);
  const GradientReport r =
      gradient(file, {}, "final:1:x", {"forces[0].params.ks", "forces[0].params.kd"}, "");
  INFO("closed form " << dks << ", " << dkd << "; adjoint " << r.paths[0].gradient[0] << ", "
                      << r.paths[1].gradient[0]);
  CHECK(r.paths[0].gradient[0] == Approx(dks).epsilon(1e-5));
  CHECK(r.paths[1].gradient[0] == Approx(dkd).epsilon(1e-5));
}

TEST_CASE("scene gradient: checkpoint segments do not change the gradient", "[gradients][scene]") {
  const std::string file = scene_file("grad_blob_seg", kBlob);
  const std::vector<std::string> wrt{"forces[1].params.ks", "forces[0].params.g"};
  const GradientReport a = gradient(file, {}, "final:2:x", wrt, "", 1);
  const GradientReport b = gradient(file, {}, "final:2:x", wrt, "", 0);
  const GradientReport c = gradient(file, {}, "final:2:x", wrt, "", 300);
  CHECK(a.peak_states > b.peak_states);
  CHECK(c.peak_states > b.peak_states);
  for (std::size_t k = 0; k < wrt.size(); ++k) {
    CHECK(a.paths[k].gradient == b.paths[k].gradient);
    CHECK(c.paths[k].gradient == b.paths[k].gradient);
  }
  CHECK(a.state_hash == b.state_hash);
}

TEST_CASE("scene gradient: bad paths name themselves", "[gradients][scene]") {
  const std::string file = PINSIM_SOURCE_DIR "/configs/projectile.json";
  auto message = [&](const std::string& path) {
    try {
      (void)gradient(file, {}, "final:0:x", {path}, "");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  CHECK_THAT(message("particles[3].v"),
             Catch::Contains("--wrt particles[3].v") && Catch::Contains("has 1 entries"));
  CHECK_THAT(message("time.dt"), Catch::Contains("--wrt time.dt: not differentiable"));
  CHECK_THAT(message("forces[0].params.q"), Catch::Contains("no parameter 'q'"));
  CHECK_THAT(message("forces[0].params.mode"), Catch::Contains("not differentiable"));
  CHECK_THAT(message("particles[0].radius"), Catch::Contains("not differentiable"));
  CHECK_THAT(message("nothing.here"), Catch::Contains("the scene has no 'nothing'"));
}

TEST_CASE("scene gradient: integrators and backends without an adjoint are refused",
          "[gradients][scene]") {
  const std::string file = PINSIM_SOURCE_DIR "/configs/projectile.json";
  CHECK_THROWS_WITH(gradient(file, {}, "final:0:x", {"particles[0].v"}, "rk4"),
                    Catch::Contains("integrator 'rk4' has no adjoint step"));
  CHECK_THROWS_WITH(gradient(PINSIM_SOURCE_DIR "/configs/blob_drop.json", {}, "final:0:x",
                             {"forces[1].params.ks"}, ""),
                    Catch::Contains("backend 'sdf' cannot differentiate its step"));
}
