// pinsim crosscheck SCENE [--backends sdf,box2d] [--out DIR] [--set PATH=VALUE]...
// Runs the scene on two backends and compares them (crosscheck.hpp); exit status 1 when
// the scene's tolerances ("crosscheck" object) fail or the report cannot be written, 2 on
// bad input, 128 + the signal when SIGINT, SIGTERM, SIGHUP or SIGQUIT stopped it (the
// report then says how far each run got).
#include <spdlog/spdlog.h>

#include <filesystem>
#include <iostream>
#include <memory>

#include "cli_common.hpp"
#include "commands.hpp"
#include "core/output_file.hpp"
#include "core/stop_signals.hpp"
#include "tools/crosscheck.hpp"

namespace pinsim::cli {
namespace {

struct CrosscheckArgs {
  std::string scene;
  std::string backends;
  std::string out;
  std::vector<std::string> set;
};

/// report.json and report.txt in `out`, each written atomically. Throws OutputError.
void write_report(const std::filesystem::path& dir, const nlohmann::json& j,
                  const std::string& text) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw OutputError(dir.string() + ": cannot create (" + ec.message() + ")");
  write_file_atomically(dir / "report.json", j.dump(1) + "\n");
  write_file_atomically(dir / "report.txt", text);
  spdlog::info("report written to {}", (dir / "report.json").string());
}

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
  install_stop_handlers();
  std::vector<CrosscheckRun> runs;
  for (const auto& b : spec.backends) {
    if (stop_signal().load() != 0) break;
    spdlog::info("{}: running on {} ({} steps)", scene.label, b, scene.steps());
    // With --out, each backend's run folder beside the report: render of the folder
    // overlays them.
    const std::filesystem::path run_dir = std::filesystem::path(a.out) / b;
    runs.push_back(run_for_crosscheck(scene, loader, b, spec, a.out.empty() ? nullptr : &run_dir));
  }
  bool cut = runs.size() < spec.backends.size();
  for (const auto& r : runs) cut = cut || r.stopped_by != 0;
  if (const int sig = stop_signal().load(); sig != 0 && cut) {
    // Nothing to compare: say how far each run got.
    nlohmann::json j = {{"status", "interrupted"},
                        {"signal", {{"name", signal_name(sig)}, {"number", sig}}},
                        {"scene", scene.label},
                        {"steps", scene.steps()},
                        {"runs", nlohmann::json::array()}};
    std::string text = scene.label + ": crosscheck interrupted by " + signal_name(sig) + "\n";
    for (std::size_t i = 0; i < spec.backends.size(); ++i) {
      const uint64_t done = i < runs.size() ? runs[i].steps : 0;
      j["runs"].push_back({{"backend", spec.backends[i]}, {"steps_done", done}});
      text += "  " + spec.backends[i] + ": " + std::to_string(done) + " of " +
              std::to_string(scene.steps()) + " steps\n";
    }
    std::cout << text;
    if (!a.out.empty()) write_report(a.out, j, text);
    spdlog::warn("{}: stopped by {}; run it again for a comparison", scene.label, signal_name(sig));
    return stop_exit_code(sig);
  }
  const CrosscheckReport rep = compare_runs(scene, spec, runs[0], runs[1]);
  std::cout << rep.table;
  if (!a.out.empty()) write_report(a.out, rep.json, rep.table);
  return rep.pass ? 0 : 1;
}

}  // namespace

void add_crosscheck_command(CLI::App& app) {
  auto a = std::make_shared<CrosscheckArgs>();
  CLI::App* c = app.add_subcommand(
      "crosscheck", "Run a scene on two backends and report where and why they differ");
  c->add_option("scene", a->scene, "Scene file (JSON)")->required();
  c->add_option("--backends", a->backends, "Two backends, default sdf,box2d");
  c->add_option("--out,-o", a->out,
                "Folder for report.json, report.txt and one run folder per backend (NAME/, as "
                "run --out writes; render of the folder overlays them)");
  c->add_option("--set", a->set, "Override a scene value, e.g. --set time.dt=0.0005")->take_all();
  c->callback([a] { throw CLI::RuntimeError(crosscheck_command(*a)); });
}

}  // namespace pinsim::cli
