// pinsim crosscheck SCENE [--backends sdf,box2d] [--out DIR] [--set PATH=VALUE]...
// Runs the scene on two backends and compares them (crosscheck.hpp); exit status 1 when
// the scene's tolerances ("crosscheck" object) fail, 2 on bad input.
#include <spdlog/spdlog.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>

#include "cli_common.hpp"
#include "commands.hpp"
#include "tools/crosscheck.hpp"

namespace pinsim::cli {
namespace {

struct CrosscheckArgs {
  std::string scene;
  std::string backends;
  std::string out;
  std::vector<std::string> set;
};

int crosscheck_command(const CrosscheckArgs& a) {
  Scene scene = load_scene(a.scene, a.set);
  CrosscheckSpec spec = parse_crosscheck(scene);
  if (!a.backends.empty()) {
    const auto comma = a.backends.find(',');
    if (comma == std::string::npos || a.backends.find(',', comma + 1) != std::string::npos)
      throw InputError(
          "--backends: expected two names separated by a comma, e.g. sdf,box2d; got '" +
          a.backends + "'");
    spec.backends = {a.backends.substr(0, comma), a.backends.substr(comma + 1)};
  }
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  std::vector<CrosscheckRun> runs;
  for (const auto& b : spec.backends) {
    spdlog::info("{}: running on {} ({} steps)", scene.label, b, scene.steps());
    runs.push_back(run_for_crosscheck(scene, loader, b, spec));
  }
  const CrosscheckReport rep = compare_runs(scene, spec, runs[0], runs[1]);
  std::cout << rep.table;
  if (!a.out.empty()) {
    const std::filesystem::path dir(a.out);
    std::filesystem::create_directories(dir);
    std::ofstream(dir / "report.json") << rep.json.dump(1) << "\n";
    std::ofstream(dir / "report.txt") << rep.table;
    spdlog::info("report written to {}", (dir / "report.json").string());
  }
  return rep.pass ? 0 : 1;
}

}  // namespace

void add_crosscheck_command(CLI::App& app) {
  auto a = std::make_shared<CrosscheckArgs>();
  CLI::App* c = app.add_subcommand(
      "crosscheck", "Run a scene on two backends and report where and why they differ");
  c->add_option("scene", a->scene, "Scene file (JSON)")->required();
  c->add_option("--backends", a->backends, "Two backends, default sdf,box2d");
  c->add_option("--out,-o", a->out, "Folder for report.json and report.txt");
  c->add_option("--set", a->set, "Override a scene value, e.g. --set time.dt=0.0005")->take_all();
  c->callback([a] { throw CLI::RuntimeError(crosscheck_command(*a)); });
}

}  // namespace pinsim::cli
