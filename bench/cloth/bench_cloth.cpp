// A 100 x 100 cloth (10,000 particles of 1 g, top row pinned, damped springs on the grid
// edges (ks 50) and shears (ks 20), gravity; dt = 1 ms): the cost of one step with
// symplectic Euler and with implicit Euler, and the cost of writing one trajectory frame of
// its 10,000 particles (CSV and HDF5) against one symplectic step. Prints CSV lines
// "figure,value,unit". The two integrators' steps are timed in alternating blocks in one run
// (medians, and the median of the per-round ratios): at --threads 1 in this thread's CPU
// time (all the step's work) and in wall time, at the default thread count in wall time
// (the workers' CPU is not on this thread's clock). Not a test: figures for
// docs/bench_and_stress.md.
//
// Usage: pinsim_bench_cloth [n=100] [out_dir=/tmp/pinsim_bench_cloth]
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "cloth_scene.hpp"
#include "core/plugin_loader.hpp"
#include "core/recorder.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "core/trajectory_hdf5.hpp"

namespace {

nlohmann::json cloth_scene(int n, const std::string& integrator, const std::string& format) {
  nlohmann::json doc = pinsim::bench::cloth_scene(n, integrator);
  doc["output"] = {{"format", format}};
  return doc;
}

/// This thread's CPU time, ms (wall time on a loaded shared machine mostly measures the
/// other processes).
double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

/// Wall time, ms (steady clock).
double wall_ms() {
  return 1e-6 * static_cast<double>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                        std::chrono::steady_clock::now().time_since_epoch())
                                        .count());
}

/// The median of `t` (t is reordered).
double median(std::vector<double> t) {
  std::nth_element(t.begin(), t.begin() + static_cast<std::ptrdiff_t>(t.size() / 2), t.end());
  return t[t.size() / 2];
}

/// Median thread CPU milliseconds of `fn` over `repeats` calls (after `warm` untimed calls).
double median_ms(const std::function<void()>& fn, int repeats, int warm) {
  for (int i = 0; i < warm; ++i) fn();
  std::vector<double> t;
  for (int i = 0; i < repeats; ++i) {
    const double a = cpu_ms();
    fn();
    t.push_back(cpu_ms() - a);
  }
  return median(std::move(t));
}

}  // namespace

int main(int argc, char** argv) {
  int n = 100;
  if (argc > 1) {
    const std::string_view a(argv[1]);
    const auto [end, ec] = std::from_chars(a.data(), a.data() + a.size(), n);
    if (ec != std::errc() || end != a.data() + a.size() || n < 2 || n > 1000) {
      std::fprintf(stderr, "usage: pinsim_bench_cloth [n=100, 2..1000] [out_dir]: n was '%s'\n",
                   argv[1]);
      return 2;
    }
  }
  const std::filesystem::path out = argc > 2 ? argv[2] : "/tmp/pinsim_bench_cloth";
  pinsim::PluginLoader loader(pinsim::plugin_search_dirs());
  std::printf("figure,value,unit\nparticles,%d,\n", n * n);

  // Both integrators' simulations side by side, their steps timed in alternation (per
  // round 60 symplectic steps, then 20 implicit steps; 9 rounds): the machine's speed drifts
  // by 20-30 % over seconds here (a shared virtual machine), and a ratio of two medians taken
  // seconds apart carries that drift; the median of the per-round ratios does not. Blocks
  // of steps, not single steps: a step right after the other simulation's finds oneTBB's
  // workers and the caches in another state than `pinsim run` does.
  struct Pair {
    double symplectic, implicit, ratio;
  };
  auto steps = [&](unsigned threads, int rounds, double (*clock)()) {
    auto make = [&](const char* integrator) {
      const pinsim::Scene scene =
          pinsim::parse_scene(cloth_scene(n, integrator, "csv").dump(), "cloth.json", ".");
      pinsim::RunOptions options;
      options.threads = threads;
      return std::make_unique<pinsim::Simulation>(scene, loader, options);
    };
    auto sym = make("symplectic_euler"), imp = make("implicit_euler");
    for (int i = 0; i < 5; ++i) {
      sym->step();
      imp->step();
    }
    std::vector<double> ts, ti, ratio;
    constexpr int kBlock = 20;
    for (int r = 0; r < rounds; ++r) {
      const double a = clock();
      for (int k = 0; k < 3 * kBlock; ++k) sym->step();
      const double b = clock();
      for (int k = 0; k < kBlock; ++k) imp->step();
      const double c = clock();
      ts.push_back((b - a) / (3.0 * kBlock));
      ti.push_back((c - b) / kBlock);
      ratio.push_back(ti.back() / ts.back());
    }
    return Pair{median(ts), median(ti), median(ratio)};
  };
  // One thread: this thread's CPU time is all of the step's work.
  const Pair one = steps(1, 9, cpu_ms);
  std::printf("symplectic_euler_step_1_thread,%.4f,ms\n", one.symplectic);
  std::printf("implicit_euler_step_1_thread,%.4f,ms\n", one.implicit);
  std::printf("implicit_over_symplectic_1_thread,%.2f,\n", one.ratio);
  // The same in wall time, then at the default thread count (the machine's cores), where the
  // work runs on the workers too, whose CPU time this thread's clock does not see: wall time
  // (what a user waits for).
  const Pair one_wall = steps(1, 9, wall_ms);
  std::printf("symplectic_euler_step_1_thread_wall,%.4f,ms\n", one_wall.symplectic);
  std::printf("implicit_euler_step_1_thread_wall,%.4f,ms\n", one_wall.implicit);
  std::printf("implicit_over_symplectic_1_thread_wall,%.2f,\n", one_wall.ratio);
  const Pair all = steps(0, 9, wall_ms);
  const double symplectic = all.symplectic;
  std::printf("symplectic_euler_step_wall,%.4f,ms\n", all.symplectic);
  std::printf("implicit_euler_step_wall,%.4f,ms\n", all.implicit);
  std::printf("implicit_over_symplectic_wall,%.2f,\n", all.ratio);
  {
    const pinsim::Scene scene =
        pinsim::parse_scene(cloth_scene(n, "implicit_euler", "csv").dump(), "cloth.json", ".");
    pinsim::Simulation sim(scene, loader);
    for (int i = 0; i < 50; ++i) sim.step();
    const auto st = sim.integrator_stats();
    std::printf("implicit_cg_iterations_per_solve,%.2f,\n",
                st.value("cg_iterations_per_solve", 0.0));
    std::printf("implicit_bicgstab_solves_of_50,%d,\n", st.value("bicgstab_solves", 0));
  }

  for (const char* format : {"csv", "hdf5"}) {
    if (std::string(format) == "hdf5" && !pinsim::hdf5_supported()) continue;
    const pinsim::Scene scene =
        pinsim::parse_scene(cloth_scene(n, "symplectic_euler", format).dump(), "cloth.json", ".");
    pinsim::Simulation sim(scene, loader);
    pinsim::Recorder rec(out / format, scene, true);
    for (int i = 0; i < 5; ++i) sim.step();
    const double write = median_ms([&] { rec.write_state(sim.state()); }, 101, 5);
    rec.close();
    std::printf("%s_frame_write,%.4f,ms\n", format, write);
    std::printf("%s_frame_write_over_symplectic_step,%.3f,\n", format, write / symplectic);
  }
  return 0;
}
