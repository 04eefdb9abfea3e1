// bench_gradients: the cost of `pinsim grad`. For scenes with force parameters (or, through
// the sdf backend's collisions, a material) to differentiate, per number of steps N: the forward
// pass (Simulation::step, with a checkpoint every S = ceil(sqrt(N)) steps) and the backward pass
// (each segment replayed, its adjoint steps in reverse) as median wall times over repeats, the
// median of each run's ratio of the two, the states held at once (sqrt(N) checkpoints and one
// segment's step records) against the N a taped run would hold, and the process's peak RSS. Prints
// CSV, one row per case:
//   case,integrator,particles,steps,segment,peak_states,taped_states,forward_s,backward_s,
//   backward_over_forward,peak_state_mb,taped_state_mb,max_rss_mb,gradient0
// (peak_state_mb, taped_state_mb: the states' bytes, 2 x 2N doubles for x and v plus the
// per-step record; max_rss_mb: ru_maxrss after the case, monotone over the run.)
// Usage: bench_gradients [--quick] [--full] [--repeats R]
//   --quick  small cases, a smoke test (ctest): checks it runs and prints finite figures
//   --full   adds the million-step run
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "gradients/scene_gradient.hpp"

using namespace pinsim;
using namespace pinsim::grad;

namespace {

struct Case {
  std::string name, file, integrator, loss;
  std::vector<std::string> set, wrt;
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double max_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, full = false;
  int repeats = 5;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) {
      quick = true;
    } else if (!std::strcmp(argv[i], "--full")) {
      full = true;
    } else if (!std::strcmp(argv[i], "--repeats") && i + 1 < argc) {
      repeats = std::max(1, std::atoi(argv[++i]));
    } else {
      std::fprintf(stderr, "usage: bench_gradients [--quick] [--full] [--repeats R]\n");
      return 2;
    }
  }
  if (quick) repeats = 1;
  const std::string cfg = PINSIM_CONFIG_DIR;
  std::vector<Case> cases;
  for (const char* integ : {"symplectic_euler", "velocity_verlet", "implicit_euler"})
    cases.push_back({"hair_strand",
                     cfg + "/hair_strand.json",
                     integ,
                     "final:11:y",
                     {},
                     {"forces[1].params.ks", "forces[2].params.k"}});
  cases.push_back({"two_mass_oscillator",
                   cfg + "/two_mass_oscillator.json",
                   "velocity_verlet",
                   "final:1:x",
                   {},
                   {"particles[1].v", "forces[0].params.k"}});
  cases.push_back({"projectile",
                   cfg + "/projectile.json",
                   "symplectic_euler",
                   "final:0:x",
                   {},
                   {"particles[0].v"}});
  // the sdf backend's collisions: a ball bouncing in a box (a bounce every 0.18 s)
  cases.push_back({"empty_box_bounces",
                   cfg + "/empty_box.json",
                   "symplectic_euler",
                   "final:0:x",
                   {},
                   {"particles[0].v", "obstacles[0].material.restitution"}});
  std::vector<uint64_t> steps =
      quick ? std::vector<uint64_t>{100, 400} : std::vector<uint64_t>{1000, 10000, 100000};
  if (full && !quick) steps.push_back(1000000);

  std::printf(
      "case,integrator,particles,steps,segment,peak_states,taped_states,forward_s,backward_s,"
      "backward_over_forward,peak_state_mb,taped_state_mb,max_rss_mb,gradient0\n");
  for (const Case& c : cases)
    for (const uint64_t n : steps) {
      if (c.integrator == "implicit_euler" && n > 100000) continue;  // minutes, same shape
      const Scene base = load_scene(c.file);
      std::vector<std::string> set = c.set;
      set.push_back("time.duration=" + std::to_string(static_cast<double>(n) * base.dt));
      const Scene scene = load_scene(c.file, set);
      PluginLoader loader(plugin_search_dirs(scene.plugin_path));
      GradientOptions opt;
      opt.run.integrator = c.integrator;
      opt.run.threads = 1;
      std::vector<double> fwd, bwd, ratio;
      GradientReport r;
      for (int k = 0; k < repeats; ++k) {
        r = scene_gradient(
            scene, loader, c.wrt, [&](const LossContext& x) { return parse_loss(c.loss, x); }, opt);
        fwd.push_back(r.forward_s);
        ratio.push_back(r.forward_s > 0 ? r.backward_s / r.forward_s : 0.0);
        bwd.push_back(r.backward_s);
      }
      // the ratio of each run's own passes (measured one after the other), then the median:
      // steadier on a shared machine than the ratio of the two medians
      const double f = median(fwd), b = median(bwd), q = median(ratio);
      const double np = static_cast<double>(scene.initial_state().size());
      // a state: x and v (4 doubles a particle); a step record (StepTape): its start state,
      // the drift's x and v, and velocity Verlet's x1, vc, vp; implicit Euler's also its
      // system's A^T (BlockSystem: first and diag_block 8 bytes a particle; col 4, tblock 8
      // and the values 32 a block)
      const double blocks = static_cast<double>(r.system_blocks);
      const double state_b = 4.0 * 8.0 * np,
                   record_b = 9.0 * 2.0 * 8.0 * np + (blocks > 0 ? 16.0 * np + 44.0 * blocks : 0.0);
      const double peak_mb = (static_cast<double>(r.checkpoints) * state_b +
                              static_cast<double>(r.peak_states - r.checkpoints) * record_b) /
                             1048576.0;
      const double taped_mb = static_cast<double>(r.steps) * record_b / 1048576.0;
      const double g0 = r.paths.empty() ? 0.0 : r.paths[0].gradient[0];
      std::printf("%s,%s,%.0f,%llu,%llu,%llu,%llu,%.6g,%.6g,%.3g,%.4g,%.4g,%.1f,%.17g\n",
                  c.name.c_str(), c.integrator.c_str(), np, static_cast<unsigned long long>(n),
                  static_cast<unsigned long long>(r.segment),
                  static_cast<unsigned long long>(r.peak_states),
                  static_cast<unsigned long long>(r.steps), f, b, q, peak_mb, taped_mb,
                  max_rss_mb(), g0);
      std::fflush(stdout);
      if (!(std::isfinite(f) && std::isfinite(b) && std::isfinite(g0) && r.steps == n)) {
        std::fprintf(stderr, "bench_gradients: %s: non-finite figures or wrong step count\n",
                     c.name.c_str());
        return 1;
      }
    }
  return 0;
}
