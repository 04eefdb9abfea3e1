// pinsim run [SCENE] [--out DIR] [--set PATH=VALUE]... [--backend NAME] [--integrator NAME]
//            [--threads N]
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <memory>

#include "cli_common.hpp"
#include "commands.hpp"
#include "core/crash_summary.hpp"
#include "core/format.hpp"
#include "core/runner.hpp"
#include "core/stop_signals.hpp"

namespace pinsim::cli {
namespace {

struct RunArgs {
  std::string scene;
  std::string out;
  std::vector<std::string> set;
  std::string backend;
  std::string integrator;
  unsigned threads = 0;  ///< 0 = the machine's cores
  bool overwrite = false;
};

int run_command(const RunArgs& a) {
  // A crash before run_scene arms the crash summary (a plugin that crashes while it is
  // loaded or created), or in a run without --out, leaves no summary.json: stderr says so.
  set_crash_notice(a.out.empty()
                       ? "(a run without --out writes no summary.json)"
                       : "before the run's output folder was prepared: it has no summary.json");
  Scene scene = load_scene_or_default(a.scene, with_backend(a.scene, a.backend, a.set));
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  RunSettings rs;
  rs.options.integrator = a.integrator;
  rs.options.threads = a.threads;
  if (!a.out.empty()) rs.out = a.out;
  rs.overwrite = a.overwrite;
  rs.stop = &stop_signal();
  const bool tty = ::isatty(STDERR_FILENO) && spdlog::get_level() <= spdlog::level::info;
  if (tty) {
    rs.progress = [](double frac, const Simulation& sim) {
      std::fprintf(stderr, "\r[%3d%%] t = %.4g s, step %llu   ", static_cast<int>(100 * frac),
                   sim.state().t, static_cast<unsigned long long>(sim.step_index()));
      std::fflush(stderr);
    };
  }
  install_stop_handlers();
  spdlog::debug("{}: {} particles, {} force(s), backend {}, {} steps of dt = {}", scene.label,
                scene.particles.size(), scene.forces.size(), scene.backend.name, scene.steps(),
                scene.dt);
  RunResult r = run_scene(scene, loader, rs);
  if (tty) std::fprintf(stderr, "\r%*s\r", 40, "");
  const auto& s = r.summary;
  auto text = [](const nlohmann::json& x) { return x.is_number() ? num(x.get<double>()) : "null"; };
  spdlog::info("{}: {} after {} steps (t = {} s) in {:.3f} s wall; {} contacts; energy {} -> {}",
               scene.label, s["status"].get<std::string>(), s["steps"].get<uint64_t>(),
               text(s["t_end"]), s["wall_time_s"].get<double>(), s["contacts"].get<uint64_t>(),
               text(s["energy"]["start"]), text(s["energy"]["end"]));
  if (rs.out) spdlog::info("output written to {}", rs.out->string());
  return r.exit_code;
}

}  // namespace

void add_run_command(CLI::App& app) {
  auto a = std::make_shared<RunArgs>();
  CLI::App* c = app.add_subcommand("run", "Simulate a scene and write its output");
  c->add_option("scene", a->scene, "Scene file (JSON); default: the embedded pinball table");
  c->add_option("--out,-o", a->out, "Output folder for trajectory.csv, events.csv, summary.json");
  c->add_option("--set", a->set, "Override a scene value, e.g. --set time.dt=0.0005")->take_all();
  c->add_option("--backend", a->backend,
                "Use this collision backend instead of the scene's, with the scene's "
                "crosscheck.params.NAME if it has them; --set backend.params.KEY=VALUE after it "
                "sets its parameters");
  c->add_option("--integrator", a->integrator,
                "Use this integrator instead of the scene's (explicit_euler, symplectic_euler, "
                "velocity_verlet, rk4, implicit_euler, xpbd)");
  c->add_option("--threads", a->threads,
                "Threads for the forces and the backend's particles (1 to " +
                    std::to_string(kMaxThreads) +
                    "; default: the machine's cores); the results are the same to the bit for "
                    "any number (docs/threads.md)")
      ->check(CLI::Range(1u, kMaxThreads));
  c->add_flag("--overwrite", a->overwrite, "Replace an earlier run's files in the output folder");
  c->callback([a] { throw CLI::RuntimeError(run_command(*a)); });
}

}  // namespace pinsim::cli
