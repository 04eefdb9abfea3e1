// A 100 x 100 cloth (10,000 particles of 1 g, top row pinned, damped springs on the grid
// edges (ks 50) and shears (ks 20), gravity; dt = 1 ms): the cost of one step with
// symplectic Euler and with implicit Euler, and the cost of writing one trajectory frame of
// its 10,000 particles (CSV and HDF5) against one symplectic step. Prints CSV lines
// "figure,value,unit" (medians of repeats, thread CPU time; ratios from the same run); the
// step costs at --threads 1 (all the work on this thread) and at the default thread count.
// Not a test: figures for docs/bench_and_stress.md (after issue 15's deliverable 6, load
// average 6.4: implicit 7.5 ms, 10 to 12 x a symplectic step; main before it 11.4 ms, 18.7 x).
//
// Usage: pinsim_bench_cloth [n=100] [out_dir=/tmp/pinsim_bench_cloth]
#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
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

/// Median thread CPU milliseconds of `fn` over `repeats` calls (after `warm` untimed calls).
double median_ms(const std::function<void()>& fn, int repeats, int warm) {
  for (int i = 0; i < warm; ++i) fn();
  std::vector<double> t;
  for (int i = 0; i < repeats; ++i) {
    const double a = cpu_ms();
    fn();
    t.push_back(cpu_ms() - a);
  }
  std::nth_element(t.begin(), t.begin() + repeats / 2, t.end());
  return t[static_cast<std::size_t>(repeats / 2)];
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

  auto step_ms = [&](const char* integrator, int repeats, unsigned threads) {
    const pinsim::Scene scene =
        pinsim::parse_scene(cloth_scene(n, integrator, "csv").dump(), "cloth.json", ".");
    pinsim::RunOptions options;
    options.threads = threads;
    pinsim::Simulation sim(scene, loader, options);
    return median_ms([&] { sim.step(); }, repeats, 5);
  };
  // One thread: this thread's CPU time is all of the step's work.
  const double symplectic1 = step_ms("symplectic_euler", 101, 1);
  const double implicit1 = step_ms("implicit_euler", 31, 1);
  std::printf("symplectic_euler_step_1_thread,%.4f,ms\n", symplectic1);
  std::printf("implicit_euler_step_1_thread,%.4f,ms\n", implicit1);
  std::printf("implicit_over_symplectic_1_thread,%.2f,\n", implicit1 / symplectic1);
  // The default thread count (the machine's cores): the springs' forces run in chunks on
  // the workers too, whose CPU time this thread's clock does not see.
  const double symplectic = step_ms("symplectic_euler", 101, 0);
  const double implicit = step_ms("implicit_euler", 31, 0);
  std::printf("symplectic_euler_step,%.4f,ms\n", symplectic);
  std::printf("implicit_euler_step,%.4f,ms\n", implicit);
  std::printf("implicit_over_symplectic,%.2f,\n", implicit / symplectic);
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
