// Whole runs of a scene for the gradient tests: the loss of a run as `pinsim run --set` makes
// it, the adjoint's gradient, and the check of one against central differences of the other.
#pragma once

#include <catch2/catch.hpp>
#include <charconv>
#include <cmath>
#include <string>
#include <vector>

#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "gradients/scene_gradient.hpp"
#include "test_support.hpp"

namespace pinsim::grad::testing {

/// A ring blob of damped springs under gravity, no obstacles (backend none), whose springs
/// start away from their rest lengths, so that it oscillates as it flies: its edges' ks and
/// kd leave their mark on every frame.
inline constexpr const char* kFlyingBlob = R"({
  "time": {"dt": 0.001, "duration": 0.5},
  "backend": {"name": "none"},
  "bodies": [{"type": "ring_blob", "name": "blob", "center": [0.0, 1.0], "ring_radius": 0.3,
              "count": 8, "total_mass": 0.8, "radius": 0.02, "velocity": [0.4, 0.3]}],
  "forces": [
    {"type": "gravity", "params": {"g": [0.0, -9.81]}},
    {"type": "damped_spring", "params": {"ks": 300.0, "kd": 0.4, "rest_length": 0.25},
     "elements": {"body": "blob", "set": "edges"}},
    {"type": "damped_spring", "params": {"ks": 100.0, "kd": 0.2, "rest_length": 0.55},
     "elements": {"body": "blob", "set": "cross"}}
  ],
  "output": {"every": 10}
})";

inline std::string text(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

/// A scene file written from `json` into a fresh folder.
inline std::string scene_file(const std::string& tag, const std::string& json) {
  const auto dir = test::temp_dir(tag);
  test::write_file(dir / "scene.json", json);
  return (dir / "scene.json").string();
}

/// The loss of a whole run of `file` with `overrides`: the run `pinsim run --set` makes
/// (Simulation::step, scene.steps() times), the loss summed over its step ends.
inline double run_loss(const std::string& file, const std::vector<std::string>& overrides,
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

/// `plugin_derivatives` false: every force parameter's derivative by central differences,
/// even where its plugin gives it.
inline GradientReport gradient(const std::string& file, const std::vector<std::string>& overrides,
                               const std::string& loss_spec, const std::vector<std::string>& wrt,
                               const std::string& integrator, uint64_t segment = 0,
                               bool plugin_derivatives = true) {
  const Scene scene = load_scene(file, overrides);
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  GradientOptions opt;
  opt.run.integrator = integrator;
  opt.run.threads = 1;
  opt.segment = segment;
  opt.plugin_parameter_derivatives = plugin_derivatives;
  return scene_gradient(
      scene, loader, wrt, [&](const LossContext& c) { return parse_loss(loss_spec, c); }, opt);
}

/// The assignment of a value's components with component c moved by d.
inline std::string moved(const WrtValue& w, std::size_t c, double d) {
  if (w.value.size() == 1) return w.path + "=" + text(w.value[0] + d);
  std::vector<double> v = w.value;
  v[c] += d;
  return w.path + "=[" + text(v[0]) + "," + text(v[1]) + "]";
}

/// Every component of every --wrt value against the central difference of whole runs,
///   dL/dtheta ~ (L(theta + e) - L(theta - e)) / (2 e),  e = rel_step max(|theta|, 1)
/// (truncation O(e^2 L'''/L'), about 1e-8 relative here; rounding O(1e-16 L / e)).
inline void check_against_runs(const std::string& file, const std::vector<std::string>& overrides,
                               const std::string& loss, const std::vector<std::string>& wrt,
                               const std::string& integrator, double rel = 1e-6,
                               double rel_step = 1e-4) {
  const GradientReport r = gradient(file, overrides, loss, wrt, integrator);
  REQUIRE(r.paths.size() == wrt.size());
  CHECK(r.loss == Approx(run_loss(file, overrides, loss, integrator)).epsilon(1e-14));
  for (const PathGradient& p : r.paths)
    for (std::size_t c = 0; c < p.wrt.value.size(); ++c) {
      const double e = rel_step * std::max(std::abs(p.wrt.value[c]), 1.0);
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

}  // namespace pinsim::grad::testing
