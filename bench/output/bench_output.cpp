// What writing one trajectory frame costs a run, measured as `pinsim run` writes it
// (output.every = 1, output.events none): the run loop's sim.step() then
// Recorder::write_state(), for
//   - cloth: a 100 x 100 cloth (10,000 particles, symplectic Euler, dt = 1 ms; the cloth of
//     pinsim_bench_cloth), and
//   - balls: 10,000 balls dropped at random into the pinball table (configs/pinball.json,
//     sdf backend),
// each with three writers: "csv" (trajectory.csv), "hdf5_inline" (trajectory.h5 written
// inside write_state, the writer before the writer thread) and "hdf5" (trajectory.h5 handed
// to the writer thread, what `pinsim run` does).
// Figures per variant (one run: the ratios compare costs measured side by side):
//   step_ms          median thread CPU time of sim.step()
//   write_ms         median thread CPU time of write_state() on the step's thread
//   write_over_step  write_ms / step_ms: the target is < 0.10 for 10,000 particles
//   writer_ms        CPU time per frame on other threads (the writer thread; process CPU
//                    minus the step thread's)
//   wall_over_bare   wall time of the loop with the writes (and the final drain) over the
//                    same loop without them, minus 1: what the run waits for; with a free
//                    core the writer's work is hidden, on a loaded machine it is not
// Prints CSV: case,particles,writer,steps,step_ms,write_ms,write_over_step,writer_ms,
// wall_over_bare. Also checks that "hdf5" and "hdf5_inline" wrote the same bytes (exit 1
// if not). Not a test of speed: figures for docs/bench_and_stress.md.
//
// Usage: pinsim_bench_output [--quick] [--steps N] [--out DIR]
//   --quick  20 x 20 cloth and 400 balls, 20 steps: a smoke test (ctest)
#include <time.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "bench_world.hpp"
#include "cloth_scene.hpp"
#include "core/plugin_loader.hpp"
#include "core/recorder.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "core/trajectory_hdf5.hpp"
#include "sdf_backend.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

double process_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

double thread_cpu_ms() { return 1e-6 * pinsim::bench::cpu_ns(); }

double wall_ms() {
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

/// configs/pinball.json with `balls` balls of its ball's radius dropped at random into the
/// playfield, clear of the obstacles (as bench_run's drop cases: seed 42, the same region).
json balls_scene(std::size_t balls) {
  std::ifstream in(fs::path(PINSIM_CONFIG_DIR) / "pinball.json");
  std::stringstream ss;
  ss << in.rdbuf();
  json doc = json::parse(ss.str(), nullptr, true, true);
  const double r = doc["particles"][0]["radius"];
  using pinsim::sdf::SdfBackend;
  pinsim::bench::BenchWorld<SdfBackend> probe(
      doc, pinsim::bench::params_for<SdfBackend>(doc["backend"]["params"]), {}, {}, r);
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> ux(0.05, 0.40), uy(0.35, 0.95), uv(-1.0, 1.0);
  json particles = json::array();
  for (std::size_t i = 0; i < balls; ++i) {
    double px = 0.0, py = 0.0;
    do {
      px = ux(rng);
      py = uy(rng);
    } while (probe.be->distance(pinsim::Vec2(px, py), 0.0, nullptr) < r + 1e-3);
    particles.push_back({{"x", {px, py}}, {"v", {uv(rng), uv(rng)}}, {"mass", 1.0}, {"radius", r}});
  }
  doc["particles"] = particles;
  return doc;
}

struct Figures {
  double step_ms = NAN, write_ms = NAN, writer_ms = NAN, wall_ms = NAN;
};

/// `steps` steps of `scene` with a frame after each (writer "none": no Recorder at all).
Figures measure(const json& doc, const std::string& writer, int steps, const fs::path& out,
                pinsim::PluginLoader& loader) {
  json d = doc;
  d["output"] = {{"every", 1},
                 {"events", "none"},
                 {"format", writer == "csv" || writer == "none" ? "csv" : "hdf5"}};
  const pinsim::Scene scene = pinsim::parse_scene(d.dump(), "bench.json", PINSIM_CONFIG_DIR);
  pinsim::Simulation sim(scene, loader);
  std::unique_ptr<pinsim::Recorder> rec;
  if (writer != "none")
    rec = std::make_unique<pinsim::Recorder>(out, scene, true, writer == "hdf5");
  std::vector<double> step_t, write_t;
  if (rec) rec->write_state(sim.state());
  const double wall0 = wall_ms(), proc0 = process_cpu_ms(), thread0 = thread_cpu_ms();
  for (int i = 0; i < steps; ++i) {
    const double a = thread_cpu_ms();
    sim.step();
    const double b = thread_cpu_ms();
    step_t.push_back(b - a);
    if (rec) {
      rec->write_state(sim.state());
      write_t.push_back(thread_cpu_ms() - b);
    }
  }
  if (rec) rec->close();  // the writer thread's queue drained
  Figures f;
  f.wall_ms = wall_ms() - wall0;
  f.writer_ms = ((process_cpu_ms() - proc0) - (thread_cpu_ms() - thread0)) / steps;
  f.step_ms = pinsim::bench::median(step_t);
  if (!write_t.empty()) f.write_ms = pinsim::bench::median(write_t);
  return f;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  int steps = 0;
  fs::path out;  // default: a folder of this run's own, so that two runs never share files
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") {
      quick = true;
    } else if (a == "--steps" && i + 1 < argc) {
      steps = std::atoi(argv[++i]);
    } else if (a == "--out" && i + 1 < argc) {
      out = argv[++i];
    } else {
      std::fprintf(stderr, "usage: pinsim_bench_output [--quick] [--steps N] [--out DIR]\n");
      return 2;
    }
  }
  if (steps <= 0) steps = quick ? 20 : 300;
  if (out.empty()) {
    std::string templ = (fs::temp_directory_path() / "pinsim_bench_output.XXXXXX").string();
    if (::mkdtemp(templ.data()) == nullptr) {
      std::perror("pinsim_bench_output: mkdtemp");
      return 2;
    }
    out = templ;
  }
  const int side = quick ? 20 : 100;
  pinsim::PluginLoader loader(pinsim::plugin_search_dirs());
  struct Case {
    const char* name;
    json scene;
  };
  const std::vector<Case> cases = {
      {"cloth", pinsim::bench::cloth_scene(side)},
      {"balls", balls_scene(static_cast<std::size_t>(side) * static_cast<std::size_t>(side))}};
  std::vector<std::string> writers = {"none", "csv"};
  if (pinsim::hdf5_supported()) writers.insert(writers.end(), {"hdf5_inline", "hdf5"});
  std::printf(
      "case,particles,writer,steps,step_ms,write_ms,write_over_step,writer_ms,wall_over_bare\n");
  int failures = 0;
  for (const Case& c : cases) {
    double bare_wall = NAN;
    for (const std::string& w : writers) {
      const fs::path dir = out / (std::string(c.name) + "_" + w);
      const Figures f = measure(c.scene, w, steps, dir, loader);
      if (w == "none") {
        bare_wall = f.wall_ms;
        continue;
      }
      std::printf("%s,%d,%s,%d,%.4f,%.4f,%.3f,%.4f,%.3f\n", c.name, side * side, w.c_str(), steps,
                  f.step_ms, f.write_ms, f.write_ms / f.step_ms, f.writer_ms,
                  f.wall_ms / bare_wall - 1.0);
      std::fflush(stdout);
      if (!(std::isfinite(f.step_ms) && f.step_ms > 0 && std::isfinite(f.write_ms))) {
        std::fprintf(stderr, "pinsim_bench_output: %s %s: a figure is not a number\n", c.name,
                     w.c_str());
        ++failures;
      }
    }
    // The writer thread changes when the bytes are written, never which.
    if (pinsim::hdf5_supported()) {
      const std::string a = slurp(out / (std::string(c.name) + "_hdf5") / "trajectory.h5"),
                        b = slurp(out / (std::string(c.name) + "_hdf5_inline") / "trajectory.h5");
      if (a.empty() || a != b) {
        std::fprintf(stderr,
                     "pinsim_bench_output: %s: trajectory.h5 differs with and without the writer "
                     "thread (%zu and %zu bytes)\n",
                     c.name, a.size(), b.size());
        ++failures;
      }
    }
  }
  fs::remove_all(out);
  return failures ? 1 : 0;
}
