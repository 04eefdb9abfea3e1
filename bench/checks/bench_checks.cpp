// bench_checks: ns per particle-step of whole steps with the per-step checks on (the
// default checks.kinetic_growth) and with the growth bound off (kinetic_growth 0: the
// finiteness check only), and of the checks alone (StepChecks on the same state), on
// configs/pinball.json's ball (its whole run) and on 10,000 balls dropped on that table.
// Prints CSV: case,particles,steps,variant,ns_per_particle_step,state_hash (thread CPU time,
// median of the repeats). The state hashes show the checks change nothing.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <random>
#include <string>
#include <vector>

#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "core/step_checks.hpp"

using namespace pinsim;
using nlohmann::json;
namespace {

/// This thread's CPU time, s: the figures do not count time the machine gave to others.
double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size();
  return m % 2 ? v[m / 2] : 0.5 * (v[m / 2 - 1] + v[m / 2]);
}

/// The pinball scene with `balls` balls dropped at random clear of every obstacle (1: the
/// scene as it is).
Scene make_scene(std::size_t balls, PluginLoader& loader) {
  const Scene base = load_scene(PINSIM_CONFIG_DIR "/pinball.json");
  if (balls == 1) return base;
  Simulation probe(base, loader);
  json doc = base.doc;
  json ball = doc["particles"][0];
  doc["particles"] = json::array();
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> ux(0.05, 0.40), uy(0.35, 0.95), uv(-1.0, 1.0);
  const double r = ball["radius"].get<double>();
  while (doc["particles"].size() < balls) {
    const double px = ux(rng), py = uy(rng);
    if (probe.backend().distance(px, py, 0.0, nullptr) < r + 1e-3) continue;
    ball["x"] = {px, py};
    ball["v"] = {uv(rng), uv(rng)};
    doc["particles"].push_back(ball);
  }
  return parse_scene(doc.dump(), "pinball_10000.json", base.base_dir);
}

struct Figures {
  double ns;
  uint64_t hash;
};

Figures run_steps(const Scene& scene, PluginLoader& loader, uint64_t steps, double growth) {
  Scene s = scene;
  s.kinetic_growth = growth;
  Simulation sim(s, loader);
  const double t0 = cpu_seconds();
  for (uint64_t n = 0; n < steps; ++n) sim.step();
  const double sec = cpu_seconds() - t0;
  return {1e9 * sec / static_cast<double>(steps * sim.state().size()), sim.state().hash()};
}

/// The checks alone: before_drift, after_drift and check on a fixed state, `steps` times.
double checks_alone(const Scene& scene, PluginLoader& loader, uint64_t steps, double growth) {
  Simulation sim(scene, loader);
  for (int n = 0; n < 10; ++n) sim.step();
  State s = sim.state();
  StepChecks c;
  c.start(s, 1.0, growth);
  const double t0 = cpu_seconds();
  for (uint64_t n = 0; n < steps; ++n) {
    c.before_drift(s);
    c.after_drift(s);
    if (c.check(s)) std::abort();
  }
  const double sec = cpu_seconds() - t0;
  return 1e9 * sec / static_cast<double>(steps * s.size());
}

}  // namespace

int main() {
  PluginLoader loader(plugin_search_dirs());
  struct Case {
    const char* name;
    std::size_t balls;
    uint64_t steps;
  };
  const Scene one = make_scene(1, loader);
  const Case cases[] = {{"pinball_ball", 1, one.steps()}, {"balls_10000", 10000, 300}};
  const int repeats = 5;
  std::printf("case,particles,steps,variant,ns_per_particle_step,state_hash\n");
  for (const Case& c : cases) {
    const Scene scene = c.balls == 1 ? one : make_scene(c.balls, loader);
    std::vector<double> on, off, alone_on, alone_off;
    uint64_t h_on = 0, h_off = 0;
    for (int r = 0; r < repeats; ++r) {  // alternate, so a change of load falls on both
      const Figures a = run_steps(scene, loader, c.steps, 32.0);
      const Figures b = run_steps(scene, loader, c.steps, 0.0);
      on.push_back(a.ns);
      off.push_back(b.ns);
      h_on = a.hash;
      h_off = b.hash;
      const uint64_t k = c.balls == 1 ? 1000000 : 1000;
      alone_on.push_back(checks_alone(scene, loader, k, 32.0));
      alone_off.push_back(checks_alone(scene, loader, k, 0.0));
    }
    auto row = [&](const char* variant, const std::vector<double>& v, uint64_t h) {
      std::printf("%s,%zu,%llu,%s,%.2f,%016llx\n", c.name, scene.particles.size(),
                  static_cast<unsigned long long>(c.steps), variant, median(v),
                  static_cast<unsigned long long>(h));
    };
    row("step_with_growth_bound", on, h_on);
    row("step_finite_only", off, h_off);
    row("checks_alone_growth_bound", alone_on, 0);
    row("checks_alone_finite_only", alone_off, 0);
  }
  return 0;
}
