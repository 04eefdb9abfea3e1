// Wall time per step with 1 thread and with more (RunOptions::threads, as `pinsim run
// --threads N`) on the scenes of issue 15: 10,000 balls falling onto obstacles without ball
// contacts, 1,000,000 damped springs (a 708 x 708 grid's edges), and the small scenes that
// must not get slower (one ball on the pinball table, the 16-particle blob). Prints CSV:
// scene, particles, threads, steps, wall us per step (best of `repeats` runs), speed-up over
// 1 thread, process CPU us per step (every thread, spinning and waiting included; best of
// the repeats), cpu_ratio = that CPU over the 1-thread CPU (1.0 when threads cost no extra
// work; other processes on the machine hardly change it, unlike the wall time), the serial
// fraction s of the 1-thread step (Simulation::profile: the time outside the parts that run
// on threads; a lower bound, see StepProfile) and the Amdahl bound 1 / (s + (1 - s) / N) it
// implies, one force evaluation and one drift alone (wall us), state hash (equal across
// thread counts, else the line says DIFFERS and the program exits 1).
//
// copies_speedup: the machine's own ceiling, t independent 1-thread copies of the scene run
// at once (t x the 1-thread step time over theirs; the large scenes only, else 1);
// efficiency = speedup / copies_speedup (1.0: the threads lose nothing to splitting the
// work; the rest of the gap to t is the machine's).
//
// A line "# load average: ..." (/proc/loadavg) follows each scene: on a shared machine the
// ratios mean little when the load exceeds the cores.
//
// Usage: pinsim_bench_threads [threads=hardware] [repeats=3] [scale=1] [only=SCENE]
//   scale < 1 shrinks every step count (a quick look); `only` runs one scene.
#include <Eigen/Core>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"

namespace {

using nlohmann::json;

/// The first three fields of /proc/loadavg (1, 5, 15 minutes), or "unknown".
std::string load_average() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  if (!(in >> a >> b >> c)) return "unknown";
  return a + " " + b + " " + c;
}

struct Case {
  std::string name;
  json scene;  // or null: `file`
  std::string file;
  uint64_t steps;
};

json obstacles() {
  return {{{"id", "floor"},
           {"shape", {{"type", "box"}, {"center", {0.0, -1.5}}, {"half_size", {20.0, 0.5}}}},
           {"material", {{"restitution", 0.5}, {"friction", 0.1}}}},
          {{"id", "bumper_a"},
           {"shape", {{"type", "circle"}, {"center", {1.0, 0.0}}, {"radius", 0.5}}},
           {"material", {{"restitution", 0.9}}}},
          {{"id", "bumper_b"},
           {"shape", {{"type", "capsule"}, {"a", {2.5, -0.5}}, {"b", {4.0, 0.2}}, {"radius", 0.2}}},
           {"material", {{"restitution", 0.7}}}}};
}

json balls_10k() {
  return {{"name", "balls_10k"},
          {"time", {{"dt", 0.001}, {"duration", 10.0}}},
          {"integrator", "symplectic_euler"},
          {"backend", {{"name", "sdf"}}},
          {"bodies",
           {{{"type", "grid_blob"},
             {"name", "balls"},
             {"origin", {0.0, 0.5}},
             {"nx", 100},
             {"ny", 100},
             {"spacing", 0.05},
             {"mass", 0.01},
             {"radius", 0.01},
             {"velocity", {0.5, -2.0}}}}},
          {"forces", {{{"type", "gravity"}, {"params", {{"g", {0.0, -9.81}}}}}}},
          {"obstacles", obstacles()}};
}

json springs_1m() {
  return {{"name", "springs_1m"},
          {"time", {{"dt", 0.0002}, {"duration", 10.0}}},
          {"integrator", "symplectic_euler"},
          {"backend", {{"name", "sdf"}}},
          {"bodies",
           {{{"type", "grid_blob"},
             {"name", "sheet"},
             {"origin", {0.0, 0.5}},
             {"nx", 708},
             {"ny", 708},
             {"spacing", 0.01},
             {"mass", 0.001},
             {"radius", 0.003},
             {"velocity", {0.1, -0.5}}}}},
          {"forces",
           {{{"type", "gravity"}, {"params", {{"g", {0.0, -9.81}}}}},
            {{"type", "damped_spring"},
             {"params", {{"ks", 100.0}, {"kd", 0.01}}},
             {"elements", {{"body", "sheet"}, {"set", "edges"}}}}}},
          {"obstacles", obstacles()}};
}

struct Timing {
  double ms_per_step;
  double cpu_ms_per_step;  ///< process CPU time (every thread), best of the repeats
  double serial;           ///< serial fraction of the steps (StepProfile), best repeat's
  uint64_t hash;
  double ms_forces;  ///< one compute_forces at the end state
  double ms_drift;   ///< one backend drift over dt from the end state
};

/// `profile`: RunOptions::profile (four clock reads a step: not for the small scenes, whose
/// step takes 0.1-4 us; their serial fraction prints as 1).
Timing time_case(const pinsim::Scene& scene, unsigned threads, uint64_t steps, int repeats,
                 bool profile) {
  pinsim::PluginLoader loader(pinsim::plugin_search_dirs(scene.plugin_path));
  pinsim::RunOptions o;
  o.threads = threads;
  o.profile = profile;
  double best = 1e300, cpu = 1e300, forces = 0.0, drift = 0.0, serial = 1.0;
  uint64_t hash = 0;
  for (int r = 0; r < repeats; ++r) {
    pinsim::Simulation sim(scene, loader, o);
    sim.step();  // warm-up: first touch of buffers, oneTBB's threads
    const pinsim::StepProfile p0 = sim.profile();
    const std::clock_t c0 = std::clock();
    const auto a = std::chrono::steady_clock::now();
    for (uint64_t k = 1; k < steps; ++k) sim.step();
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count();
    const double c = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
    const pinsim::StepProfile& p1 = sim.profile();
    const double ms = 1e3 * s / static_cast<double>(steps - 1);
    if (ms < best && profile)
      serial = 1.0 - (p1.threaded_s - p0.threaded_s) / std::max(1e-300, p1.step_s - p0.step_s);
    best = std::min(best, ms);
    cpu = std::min(cpu, 1e3 * c / static_cast<double>(steps - 1));
    hash = sim.state().hash();
    if (r + 1 < repeats) continue;
    // the two parts of a step that run on threads, alone
    Eigen::Matrix2Xd f;
    const int reps = 5;
    pinsim::State copy = sim.state();
    auto part = [&](auto&& fn) {
      double b = 1e300;
      for (int k = 0; k < reps; ++k) {
        const auto t0 = std::chrono::steady_clock::now();
        fn();
        b = std::min(
            b, 1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      }
      return b;
    };
    forces = part([&] { sim.compute_forces(sim.state(), f); });
    drift = part([&] {
      copy = sim.state();
      sim.drift(copy, scene.dt);
    });
  }
  return {best, cpu, serial, hash, forces, drift};
}

/// The machine's own ceiling for t threads: t independent copies of the scene, each a
/// 1-thread simulation stepped by its own std::thread, all at once; returns t times the
/// 1-thread step time `one_ms` over the copies' step time (the slowest copy's wall time per
/// step, best of the repeats). Perfectly parallel work with nothing shared gets this
/// speed-up and no more: on a virtual machine whose cores slow each other down (a shared
/// host, turbo, memory), it is below t, and the threads' speed-up is fairly read against it.
double copies_speedup(const pinsim::Scene& scene, unsigned t, uint64_t steps, int repeats,
                      double one_ms) {
  pinsim::PluginLoader loader(pinsim::plugin_search_dirs(scene.plugin_path));
  pinsim::RunOptions o;
  o.threads = 1;
  double best = 1e300;
  for (int r = 0; r < repeats; ++r) {
    std::vector<std::unique_ptr<pinsim::Simulation>> sims;
    for (unsigned k = 0; k < t; ++k) {
      sims.push_back(std::make_unique<pinsim::Simulation>(scene, loader, o));
      sims.back()->step();  // warm-up, as time_case
    }
    std::atomic<unsigned> ready{0};
    std::vector<double> wall(t, 0.0);
    std::vector<std::thread> threads;
    for (unsigned k = 0; k < t; ++k)
      threads.emplace_back([&, k] {
        ready.fetch_add(1);
        while (ready.load() < t) {
        }  // start together
        const auto a = std::chrono::steady_clock::now();
        for (uint64_t i = 1; i < steps; ++i) sims[k]->step();
        wall[k] = std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count();
      });
    for (std::thread& th : threads) th.join();
    const double slowest = *std::max_element(wall.begin(), wall.end());
    best = std::min(best, 1e3 * slowest / static_cast<double>(steps - 1));
  }
  return static_cast<double>(t) * one_ms / best;
}

}  // namespace

int main(int argc, char** argv) {
  const unsigned n = argc > 1 ? static_cast<unsigned>(std::atoi(argv[1]))
                              : std::max(1u, std::thread::hardware_concurrency());
  const int repeats = argc > 2 ? std::max(1, std::atoi(argv[2])) : 3;
  const double scale = argc > 3 ? std::atof(argv[3]) : 1.0;
  const std::string only = argc > 4 ? argv[4] : "";
  const std::string configs = PINSIM_SOURCE_DIR "/configs";
  const std::vector<Case> cases = {{"balls_10k_no_contacts", balls_10k(), "", 300},
                                   {"damped_springs_1m", springs_1m(), "", 30},
                                   {"one_ball_pinball", nullptr, configs + "/pinball.json", 20000},
                                   {"blob_16", nullptr, configs + "/blob_drop.json", 6000}};
  std::printf(
      "scene,particles,threads,steps,us_per_step,speedup,cpu_us_per_step,cpu_ratio,serial_"
      "fraction,amdahl_bound,us_forces,us_drift,state_hash,copies_speedup,efficiency\n");
  int status = 0;
  for (const Case& c : cases) {
    if (!only.empty() && c.name != only) continue;
    const pinsim::Scene scene =
        c.scene.is_null() ? pinsim::load_scene(c.file)
                          : pinsim::parse_scene(c.scene.dump(), c.name + ".json", configs);
    const uint64_t steps =
        std::min(scene.steps(), std::max<uint64_t>(3, static_cast<uint64_t>(scale * c.steps)));
    const bool profile = !c.scene.is_null();  // the two large scenes
    const Timing one = time_case(scene, 1, steps, repeats, profile);
    for (unsigned t : {1u, n}) {
      const Timing m = t == 1 ? one : time_case(scene, t, steps, repeats, profile);
      // the large scenes only (the small ones' threads are skipped by design)
      const double ceiling =
          t == 1 || !profile ? 1.0 : copies_speedup(scene, t, steps, repeats, one.ms_per_step);
      const bool same = m.hash == one.hash;
      if (!same) status = 1;
      // Amdahl: the serial fraction (measured with 1 thread) runs alone, the rest on t threads
      const double amdahl = 1.0 / (one.serial + (1.0 - one.serial) / t);
      std::printf("%s,%zu,%u,%llu,%.3f,%.2f,%.3f,%.3f,%.4f,%.2f,%.3f,%.3f,%016llx%s,%.2f,%.2f\n",
                  c.name.c_str(), scene.particles.size(), t, static_cast<unsigned long long>(steps),
                  1e3 * m.ms_per_step, one.ms_per_step / m.ms_per_step, 1e3 * m.cpu_ms_per_step,
                  m.cpu_ms_per_step / one.cpu_ms_per_step, one.serial, amdahl, 1e3 * m.ms_forces,
                  1e3 * m.ms_drift, static_cast<unsigned long long>(m.hash), same ? "" : " DIFFERS",
                  ceiling, one.ms_per_step / m.ms_per_step / ceiling);
      std::fflush(stdout);
      if (n == 1) break;
    }
    std::printf("# load average: %s\n", load_average().c_str());
  }
  return status;
}
