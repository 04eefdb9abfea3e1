// XPBD against implicit Euler and symplectic Euler (with substeps) at large time steps. Prints
// four CSV tables (each after a "# name" line); figures for docs/xpbd.md, not a test:
//  cost       the 100 x 100 cloth (bench/cloth) at dt = 1/60: thread CPU ms of one xpbd
//             substep (1 iteration) against one symplectic Euler step and one implicit Euler
//             step, --threads 1, medians of alternating blocks.
//  precision  a ring blob (24 particles, ring/cross/shear springs and area pressure of ks =
//             1e3 and 1e5, h w_max ~ 10 and ~ 100 at dt = 1/60), squeezed and spinning, no gravity:
//             RMS position error at t = 1 s against symplectic Euler at dt = 1e-6 s, and the
//             thread CPU time of the run, for xpbd (substeps x iterations), implicit Euler and
//             symplectic Euler with substeps (dt / s).
//  damping    x'' = -w^2 x, w = 2 pi, 10 s at dt = 1/60: E(10 s) / E(0) against the closed forms
//             (1 + (w hs)^2)^-N (backward Euler, which one sweep per substep is) and 1 (exact).
//  stiffness  a chain of 10 particles hanging from a pinned one on springs k (h w ~ 8 at
//             dt = 1/60), damped to rest over 20 s, 1 substep: effective stiffness
//             k * (exact stretch / measured stretch) against iterations.
//  sag        the 100 x 100 cloth (cost's scene) released at rest, 2 s: the height of the
//             bottom row's middle particle (50) and the total energy, xpbd at dt = 1/60 with
//             1 to 64 substeps of one sweep against symplectic Euler at dt = 5e-4.
//
// Usage: pinsim_bench_xpbd [section]   (cost, precision, damping, stiffness, sag; default
// all)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "../cloth/cloth_scene.hpp"
#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"

namespace {

using nlohmann::json;

double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

double median(std::vector<double> t) {
  std::nth_element(t.begin(), t.begin() + static_cast<std::ptrdiff_t>(t.size() / 2), t.end());
  return t[t.size() / 2];
}

std::unique_ptr<pinsim::Simulation> make(pinsim::PluginLoader& loader, const json& doc) {
  const pinsim::Scene scene = pinsim::parse_scene(doc.dump(), "bench_xpbd.json", ".");
  pinsim::RunOptions options;
  options.threads = 1;
  return std::make_unique<pinsim::Simulation>(scene, loader, options);
}

json with_integrator(json doc, const std::string& integrator, double dt, int substeps = 1,
                     int iterations = 1) {
  doc["integrator"] = integrator;
  doc["time"]["dt"] = dt;
  doc["xpbd"] = {{"substeps", substeps}, {"iterations", iterations}};
  doc["checks"] = {{"energy_blowup", 1e300}, {"kinetic_growth", 0}};
  return doc;
}

void cost(pinsim::PluginLoader& loader) {
  std::printf(
      "# cost\nsubsteps,xpbd_substep_ms,symplectic_step_ms,implicit_step_ms,"
      "xpbd_substep_over_symplectic,implicit_over_symplectic\n");
  const json cloth = pinsim::bench::cloth_scene(100);
  for (int substeps : {1, 4}) {
    auto x = make(loader, with_integrator(cloth, "xpbd", 1.0 / 60.0, substeps, 1));
    auto s = make(loader, with_integrator(cloth, "symplectic_euler", 1e-3));
    auto i = make(loader, with_integrator(cloth, "implicit_euler", 1e-3));
    for (int k = 0; k < 3; ++k) {
      x->step();
      s->step();
      i->step();
    }
    std::vector<double> tx, ts, ti, r;
    for (int round = 0; round < 7; ++round) {
      const double a = cpu_ms();
      for (int k = 0; k < 10; ++k) x->step();
      const double b = cpu_ms();
      for (int k = 0; k < 10 * substeps; ++k) s->step();
      const double c = cpu_ms();
      for (int k = 0; k < 3; ++k) i->step();
      const double d = cpu_ms();
      tx.push_back((b - a) / (10.0 * substeps));
      ts.push_back((c - b) / (10.0 * substeps));
      ti.push_back((d - c) / 3.0);
      r.push_back(tx.back() / ts.back());
    }
    std::printf("%d,%.4f,%.4f,%.4f,%.2f,%.2f\n", substeps, median(tx), median(ts), median(ti),
                median(r), median(ti) / median(ts));
  }
}

/// The ring blob of stiffness ks, squeezed and spinning: every particle's initial velocity is
/// 1 m/s x |y|/R towards the horizontal axis plus a rotation at 2 rad/s about the centre, so the
/// ring flattens and springs back while it turns. No gravity, no obstacles.
json ring_blob(double ks) {
  json doc = json::parse(R"({"time": {"dt": 0.01, "duration": 1.0}, "backend": "none",
    "bodies": [{"type": "ring_blob", "name": "blob", "center": [0, 0], "ring_radius": 0.5,
                "count": 24, "total_mass": 1.0}],
    "forces": [{"type": "damped_spring", "params": {"kd": 0.0},
                "elements": {"body": "blob", "set": "edges"}},
               {"type": "damped_spring", "params": {"kd": 0.0},
                "elements": {"body": "blob", "set": "cross"}},
               {"type": "damped_spring", "params": {"kd": 0.0},
                "elements": {"body": "blob", "set": "shear"}},
               {"type": "area_pressure", "params": {},
                "elements": {"body": "blob", "set": "boundary"}}]})");
  for (int f = 0; f < 3; ++f) doc["forces"][f]["params"]["ks"] = ks;
  doc["forces"][3]["params"]["k"] = ks;
  return doc;
}

void precision(pinsim::PluginLoader& loader) {
  std::printf("# precision\nks,integrator,substeps,iterations,dt,cpu_ms,rms_error_m\n");
  for (double ks : {1e3, 1e5}) {
    auto run = [&](const std::string& integrator, double dt, int substeps, int iterations,
                   Eigen::Matrix2Xd* out) {
      auto sim = make(loader, with_integrator(ring_blob(ks), integrator, dt, substeps, iterations));
      pinsim::State& s = sim->state();
      for (Eigen::Index i = 0; i < s.x.cols(); ++i)
        s.v.col(i) = Eigen::Vector2d(0.0, s.x(1, i) > 0 ? -1.0 : 1.0) * std::abs(s.x(1, i)) / 0.5 +
                     2.0 * Eigen::Vector2d(-s.x(1, i), s.x(0, i));
      const double a = cpu_ms();
      const uint64_t n = sim->scene().steps();
      try {
        for (uint64_t k = 0; k < n; ++k) sim->step();
      } catch (const std::exception&) {
        out->setConstant(2, s.x.cols(), NAN);
        return cpu_ms() - a;
      }
      *out = s.x;
      return cpu_ms() - a;
    };
    Eigen::Matrix2Xd ref, x;
    run("symplectic_euler", 1e-6, 1, 1, &ref);
    auto row = [&](const std::string& integrator, double dt, int substeps, int iterations) {
      const double ms = run(integrator, dt, substeps, iterations, &x);
      const double err = std::sqrt((x - ref).colwise().squaredNorm().mean());
      std::printf("%g,%s,%d,%d,%.6g,%.2f,%.3e\n", ks, integrator.c_str(), substeps, iterations, dt,
                  ms, err);
    };
    const double dt = 1.0 / 60.0;
    for (int s : {1, 4, 16, 64, 256}) row("xpbd", dt, s, 1);
    for (int it : {4, 16}) row("xpbd", dt, 1, it);
    row("xpbd", dt, 16, 4);
    row("implicit_euler", dt, 1, 1);
    row("implicit_euler", dt / 16, 1, 1);
    for (int s : {4, 16, 64, 256, 1024}) row("symplectic_euler", dt / s, 1, 1);
  }
}

void damping(pinsim::PluginLoader& loader) {
  std::printf("# damping\nintegrator,substeps,energy_ratio_10s,closed_form\n");
  const double w = 2.0 * M_PI, dt = 1.0 / 60.0, T = 10.0;
  const json osc = json::parse(R"({"time": {"dt": 0.01, "duration": 10.0}, "backend": "none",
    "particles": [{"x": [0, 0], "pinned": true}, {"x": [1, 0], "mass": 1.0}],
    "forces": [{"type": "linear_spring", "params": {"rest_length": 0.0},
                "elements": [[0, 1]]}]})");
  auto row = [&](const std::string& integrator, int substeps) {
    json doc = with_integrator(osc, integrator, dt, substeps, 1);
    doc["forces"][0]["params"]["k"] = w * w;
    auto sim = make(loader, doc);
    const double e0 = sim->kinetic_energy(sim->state()) + sim->potential_energy(sim->state());
    for (uint64_t k = 0; k < sim->scene().steps(); ++k) sim->step();
    const double e = sim->kinetic_energy(sim->state()) + sim->potential_energy(sim->state());
    const double hs = integrator == "xpbd" ? dt / substeps : dt;
    const double closed =
        integrator == "symplectic_euler" ? 1.0 : std::pow(1.0 + w * w * hs * hs, -T / hs);
    std::printf("%s,%d,%.6f,%.6f\n", integrator.c_str(), substeps, e / e0, closed);
  };
  for (int s : {1, 4, 10, 100}) row("xpbd", s);
  row("implicit_euler", 1);
  row("symplectic_euler", 1);
}

void stiffness(pinsim::PluginLoader& loader) {
  std::printf("# stiffness\niterations,substeps,effective_k_over_k\n");
  // 10 free particles of 0.1 kg below a pinned one, 0.1 m apart, springs k = 1000 N/m (rest
  // length 0.1) with damping: spring j (from the top) carries the weight of the 10 - j + 1
  // particles below it, so the exact total stretch is sum_j (11 - j) m g / k = 55 m g / k.
  const double k = 1000.0, m = 0.1, g = 9.81;
  json doc = json::parse(R"({"time": {"dt": 0.01, "duration": 20.0}, "backend": "none",
    "forces": [{"type": "gravity", "params": {"g": [0, -9.81]}},
               {"type": "damped_spring", "params": {"ks": 1000.0, "kd": 2.0, "rest_length": 0.1},
                "elements": []}]})");
  doc["particles"] = json::array({{{"x", {0.0, 0.0}}, {"pinned", true}}});
  for (int i = 1; i <= 10; ++i) {
    doc["particles"].push_back({{"x", {0.0, -0.1 * i}}, {"mass", m}});
    doc["forces"][1]["elements"].push_back({i - 1, i});
  }
  const double exact = 55.0 * m * g / k;
  for (int substeps : {1, 10})
    for (int it : {1, 2, 4, 8, 16, 32, 64}) {
      auto sim = make(loader, with_integrator(doc, "xpbd", 1.0 / 60.0, substeps, it));
      for (uint64_t s = 0; s < sim->scene().steps(); ++s) sim->step();
      const double stretch = -sim->state().x(1, 10) - 1.0;
      std::printf("%d,%d,%.4f\n", it, substeps, exact / stretch);
    }
}

void sag(pinsim::PluginLoader& loader) {
  std::printf("# sag\nintegrator,substeps,dt,y_bottom_middle_m,energy_start_J,energy_2s_J\n");
  json cloth = pinsim::bench::cloth_scene(100);
  cloth["time"]["duration"] = 2.0;
  auto row = [&](const std::string& integrator, double dt, int substeps) {
    auto sim = make(loader, with_integrator(cloth, integrator, dt, substeps, 1));
    const double e0 = sim->kinetic_energy(sim->state()) + sim->potential_energy(sim->state());
    for (uint64_t k = 0; k < sim->scene().steps(); ++k) sim->step();
    const double e = sim->kinetic_energy(sim->state()) + sim->potential_energy(sim->state());
    std::printf("%s,%d,%.6g,%.4f,%.4g,%.4g\n", integrator.c_str(), substeps, dt,
                sim->state().x(1, 50), e0, e);
  };
  for (int s : {1, 4, 16, 64}) row("xpbd", 1.0 / 60.0, s);
  row("symplectic_euler", 5e-4, 1);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string only = argc > 1 ? argv[1] : "";
  pinsim::PluginLoader loader(pinsim::plugin_search_dirs());
  const std::vector<std::pair<std::string, std::function<void()>>> sections = {
      {"cost", [&] { cost(loader); }},
      {"precision", [&] { precision(loader); }},
      {"damping", [&] { damping(loader); }},
      {"stiffness", [&] { stiffness(loader); }},
      {"sag", [&] { sag(loader); }}};
  for (const auto& [name, fn] : sections)
    if (only.empty() || only == name) fn();
  return 0;
}
