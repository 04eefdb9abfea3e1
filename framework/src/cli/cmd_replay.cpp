// pinsim replay RUN_DIR [--out FILE.html] [--scene FILE] [--width W] [--view x0,y0,x1,y1]
#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>

#include "cli_common.hpp"
#include "commands.hpp"
#include "pictures/replay.hpp"

namespace pinsim::cli {
namespace {
namespace fs = std::filesystem;

struct ReplayArgs {
  std::string run;
  std::string out;
  std::string scene;
  std::vector<std::string> set;
  int width = 640;
  std::string view;
};

int replay_command(const ReplayArgs& a) {
  const RunData run = read_run_folder(a.run);
  std::optional<Scene> scene;
  if (!a.scene.empty())
    scene = load_scene(a.scene, a.set);
  else
    scene = run_scene(run, a.set);
  if (!scene)
    spdlog::warn(
        "the run's scene was not found (no scene.json in the run folder, summary.json "
        "\"scene\" not found); the page shows no obstacles (give it with --scene)");
  ReplayOptions opt;
  opt.width = a.width;
  if (!a.view.empty()) opt.view = view_option(a.view);
  const fs::path out = a.out.empty() ? fs::path(a.run) / "replay.html" : fs::path(a.out);
  PluginLoader loader(plugin_search_dirs(scene ? scene->plugin_path : std::vector<fs::path>{}));
  const PixelMap map = write_replay(run, scene ? &*scene : nullptr, loader, opt, out);
  spdlog::info("replay page written to {} ({} x {} canvas, {:.3f} s of run)", out.string(),
               map.width, map.height, run.t_end());
  return 0;
}

}  // namespace

void add_replay_command(CLI::App& app) {
  auto a = std::make_shared<ReplayArgs>();
  CLI::App* c = app.add_subcommand(
      "replay", "Write one self-contained HTML page that plays a run (works offline)");
  c->add_option("run", a->run, "Run folder (from pinsim run --out)")->required();
  c->add_option("--out,-o", a->out, "HTML file (default: RUN_DIR/replay.html)");
  c->add_option("--scene", a->scene, "Scene for the obstacles (default: the run's summary.json)");
  c->add_option("--set", a->set, "Override a scene value, e.g. --set time.dt=0.0005")->take_all();
  c->add_option("--width,-w", a->width, "Canvas width, pixels")->check(CLI::Range(64, 4096));
  c->add_option("--view", a->view, "World rectangle x0,y0,x1,y1 (default: fit everything)");
  c->callback([a] { throw CLI::RuntimeError(replay_command(*a)); });
}

}  // namespace pinsim::cli
