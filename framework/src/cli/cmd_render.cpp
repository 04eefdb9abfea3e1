// pinsim render SCENE|RUN_DIR... [--out FILE.png|FILE.svg] [--scene FILE] [--time T]
//   [--width W] [--view x0,y0,x1,y1] [--no-field] [--no-trajectories] [--no-contacts]
#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>

#include "cli_common.hpp"
#include "commands.hpp"
#include "core/input_error.hpp"
#include "pictures/render.hpp"

namespace pinsim::cli {
namespace {
namespace fs = std::filesystem;

struct RenderArgs {
  std::vector<std::string> inputs;
  std::string out;
  std::string scene;
  std::vector<std::string> set;
  double time = -1;
  int width = 900;
  std::string view;
  bool no_field = false, no_trajectories = false, no_contacts = false;
};

int render_command(const RenderArgs& a) {
  RenderJob job;
  std::string scene_file = a.scene;
  fs::path default_out;
  for (const auto& in : a.inputs) {
    const fs::path p = in;
    std::error_code ec;
    if (!fs::exists(p, ec))
      throw InputError(in + ": no such " +
                       (p.extension() == ".json" ? std::string("scene file")
                                                 : std::string("run folder or scene file")) +
                       " (render takes a scene file, run folders, or a folder of run folders)");
    if (fs::is_directory(p)) {
      std::vector<fs::path> dirs;
      if (is_run_dir(p))
        dirs.push_back(p);
      else
        dirs = sub_run_dirs(p);  // e.g. a crosscheck report: one run per backend
      if (dirs.empty())
        throw InputError(
            in + ": not a run folder (expected trajectory.csv or trajectory.h5 in it or in its " +
            "subfolders, as pinsim run or crosscheck --out writes)");
      for (const auto& d : dirs) job.runs.push_back(read_run_folder(d));
      if (default_out.empty()) default_out = p / "picture.png";
    } else {
      if (!scene_file.empty() && scene_file != in)
        throw InputError(in + ": only one scene per picture (already " + scene_file + ")");
      scene_file = in;
      if (default_out.empty()) default_out = fs::path(in).replace_extension(".png").filename();
    }
  }
  if (!scene_file.empty())
    job.scene = load_scene(scene_file, a.set);
  else
    for (const auto& r : job.runs)
      if ((job.scene = run_scene(r, a.set))) break;
  if (!job.scene && !job.runs.empty())
    spdlog::warn(
        "the run's scene was not found (no scene.json in the run folder, summary.json "
        "\"scene\" not found); drawing without obstacles (give it with --scene)");
  if (!job.scene && job.runs.empty())
    throw InputError("render: nothing to draw (expected a scene file or a run folder)");

  RenderOptions opt;
  opt.width = a.width;
  if (!a.view.empty()) opt.view = view_option(a.view);
  if (a.time >= 0) opt.time = a.time;
  opt.field = !a.no_field;
  opt.trajectories = !a.no_trajectories;
  opt.contacts = !a.no_contacts;
  const fs::path out = a.out.empty() ? default_out : fs::path(a.out);
  PluginLoader loader(
      plugin_search_dirs(job.scene ? job.scene->plugin_path : std::vector<fs::path>{}));
  const PixelMap map = render_picture(job, loader, opt, out);
  spdlog::info("picture written to {} ({} x {} pixels, {:.4g} pixels per unit)", out.string(),
               map.width, map.height, map.scale);
  return 0;
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto a = std::make_shared<RenderArgs>();
  CLI::App* c = app.add_subcommand(
      "render", "Draw a scene, a run, or several runs overlaid (a crosscheck) as PNG or SVG");
  c->add_option("inputs", a->inputs,
                "A scene file, run folders (or a folder of run folders), or both")
      ->required();
  c->add_option("--out,-o", a->out,
                "Picture file, .png or .svg (default: picture.png in the "
                "run folder, or SCENE.png here)");
  c->add_option("--scene", a->scene, "Scene for the obstacles (default: the run's summary.json)");
  c->add_option("--set", a->set, "Override a scene value, e.g. --set time.dt=0.0005")->take_all();
  c->add_option("--time,-t", a->time, "Time to draw, s (default: 0 for a scene, the run's end)");
  c->add_option("--width,-w", a->width, "Picture width, pixels")->check(CLI::Range(64, 8192));
  c->add_option("--view", a->view, "World rectangle x0,y0,x1,y1 (default: fit everything)");
  c->add_flag("--no-field", a->no_field,
              "Do not shade the distance field (the obstacles are still drawn, filled)");
  c->add_flag("--no-trajectories", a->no_trajectories, "Do not draw the paths");
  c->add_flag("--no-contacts", a->no_contacts, "Do not mark contacts");
  c->callback([a] { throw CLI::RuntimeError(render_command(*a)); });
}

}  // namespace pinsim::cli
