// `pinsim check-plugin NAME|PATH`: the physics check of a force plugin (plugin_check.hpp).
// Skipped checks are counted and listed; --strict fails on them, and --rubric R names the
// rubric's tests that score a check skipped here (the grader fails those: 0 points).
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"
#include "core/data_files.hpp"
#include "core/format.hpp"
#include "core/input_error.hpp"
#include "core/json_read.hpp"
#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "grading/rubric.hpp"
#include "tools/check_layout.hpp"
#include "tools/plugin_check.hpp"

namespace pinsim::cli {

namespace {

struct CheckPluginArgs {
  std::string plugin;
  std::vector<std::string> params;  ///< key=value, value parsed as JSON when it is JSON
  std::string params_json;
  uint64_t seed = CheckOptions{}.seed;
  int trials = CheckOptions{}.trials;
  bool assume_internal = false;
  bool json = false;
  std::string topology;
  std::string scene;
  std::size_t force_index = 0;
  std::vector<std::string> plugin_path;
  bool strict = false;
  std::string rubric;
};

/// A rubric test that scores a check this run skipped.
struct ScoredSkip {
  std::size_t number;  ///< the test's number in the rubric (from 1)
  std::string name, check;
  double points;
};

bool internal_check(const std::string& c) {
  return c == "momentum" || c == "angular_momentum" || c == "rigid_invariance";
}

/// The tests of `rubric` about `plugin` whose check was skipped in `rep`. A test with
/// assume_internal runs the internal-force checks whatever the flags say: it is listed in
/// `forced` instead (check-plugin --assume-internal shows its verdict).
std::vector<ScoredSkip> scored_skips(const Rubric& rubric, const CheckReport& rep,
                                     std::vector<ScoredSkip>& forced) {
  std::vector<ScoredSkip> out;
  for (std::size_t i = 0; i < rubric.tests.size(); ++i) {
    const RubricTest& t = rubric.tests[i];
    const CheckResult* c = rep.find(t.check);
    if (t.plugin != rep.plugin || c == nullptr || c->status != CheckStatus::Skip) continue;
    const bool assumed = t.spec.value("assume_internal", false) && internal_check(t.check);
    (assumed ? forced : out).push_back({i + 1, t.name, t.check, t.points});
  }
  return out;
}

nlohmann::json parse_params(const CheckPluginArgs& a) {
  nlohmann::json p = nlohmann::json::object();
  if (!a.params_json.empty()) {
    p = parse_json_text(a.params_json, "--params");
    if (!p.is_object()) throw InputError("--params: expected a JSON object, got " + a.params_json);
  }
  for (const auto& kv : a.params) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos || eq == 0)
      throw InputError("--param " + kv + ": expected key=value");
    const std::string key = kv.substr(0, eq), value = kv.substr(eq + 1);
    // a JSON value (within the scene parser's limits), else, if not JSON at all, the text
    try {
      p[key] = parse_json_text(value, "--param " + key);
    } catch (const JsonSyntaxError&) {
      p[key] = value;
    }
  }
  return p;
}

int run_check_plugin(const CheckPluginArgs& a) {
  try {
    std::shared_ptr<const LoadedPlugin> plugin;
    // Search order: --plugin-path, the scene's plugin_path, then the usual places
    // ($PINSIM_PLUGIN_PATH, the install, the build tree).
    std::vector<std::filesystem::path> dirs(a.plugin_path.begin(), a.plugin_path.end());
    std::optional<Scene> scene;
    if (!a.scene.empty()) {
      scene = load_scene(a.scene);
      dirs.insert(dirs.end(), scene->plugin_path.begin(), scene->plugin_path.end());
    }
    std::string name = a.plugin;
    if (name.empty()) {
      if (!scene) throw InputError("give a plugin name or path, or --scene with --force-index");
      if (a.force_index >= scene->forces.size())
        throw InputError(scene->label + ": --force-index " + std::to_string(a.force_index) +
                         ": the scene has " + std::to_string(scene->forces.size()) + " force(s)");
      name = scene->forces[a.force_index].name;
    }
    PluginLoader loader(plugin_search_dirs(dirs));
    const bool is_path = name.find('/') != std::string::npos ||
                         (name.size() > 3 && name.substr(name.size() - 3) == ".so");
    plugin = is_path ? loader.load_path(name, "") : loader.load(name);
    CheckOptions opt;
    opt.topology = a.topology;
    if (scene) {
      opt.scene = &*scene;
      opt.force_index = a.force_index;
    }
    opt.params = parse_params(a);
    opt.seed = a.seed;
    opt.trials = a.trials;
    opt.assume_internal = a.assume_internal;
    const CheckReport rep = check_force_plugin(*plugin, opt);
    std::vector<std::string> skipped;
    for (const auto& c : rep.checks)
      if (c.status == CheckStatus::Skip) skipped.push_back(c.name);
    std::optional<Rubric> rubric;
    if (!a.rubric.empty()) rubric = load_rubric(find_data_file(a.rubric, "configs/grading"));
    std::vector<ScoredSkip> forced;
    const std::vector<ScoredSkip> scored =
        rubric ? scored_skips(*rubric, rep, forced) : std::vector<ScoredSkip>{};
    double lost = 0.0;
    for (const auto& s : scored) lost += s.points;
    // A skip fails with --strict, and always when the given rubric scores it.
    const bool passed = rep.passed() && scored.empty() && !(a.strict && !skipped.empty());
    if (a.json) {
      nlohmann::json j = report_json(rep);
      j["skipped"] = skipped;
      j["strict"] = a.strict;
      j["passed"] = passed;
      if (rubric) {
        j["rubric"] = rubric->name;
        j["scored_skips"] = nlohmann::json::array();
        for (const auto& s : scored)
          j["scored_skips"].push_back(
              {{"test", s.number}, {"name", s.name}, {"check", s.check}, {"points", s.points}});
      }
      std::cout << j.dump(2) << "\n";
      return passed ? 0 : 1;
    }
    std::cout << format_report(rep);
    for (const auto& s : scored)
      std::cout << "scored by the grader: test " << s.number << " \"" << s.name << "\" ("
                << num(s.points) << (s.points == 1 ? " point" : " points") << ") of rubric \""
                << rubric->name << "\" runs " << s.check << ", skipped here: the grader fails it\n";
    for (const auto& s : forced)
      std::cout << "note: test " << s.number << " \"" << s.name << "\" of rubric \"" << rubric->name
                << "\" runs " << s.check
                << " with assume_internal: --assume-internal shows its verdict here\n";
    if (!skipped.empty() && !rubric)
      std::cout << "note: pinsim grade fails a skipped check where its rubric scores it (0 "
                   "points); --rubric R names those tests, --strict fails here too\n";
    if (rep.passed() && !scored.empty())
      std::cout << "FAIL: " << rep.plugin << ", " << scored.size() << " skipped check(s) scored by "
                << "rubric \"" << rubric->name << "\" (" << num(lost) << " points)\n";
    else if (rep.passed() && !passed)
      std::cout << "FAIL (--strict): " << rep.plugin << ", " << skipped.size()
                << " check(s) skipped\n";
    return passed ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "pinsim check-plugin: " << e.what() << "\n";
    return 2;
  }
}

}  // namespace

void add_check_plugin_command(CLI::App& app) {
  auto args = std::make_shared<CheckPluginArgs>();
  CLI::App* cmd = app.add_subcommand(
      "check-plugin",
      "Check a force plugin's physics on random states: f = -grad E, df/dx, df/dv by finite "
      "differences, momentum, rigid invariance, degenerate states, dissipation");
  cmd->add_option("plugin", args->plugin,
                  "plugin name (searched) or path to a .so file; with --scene, default: the "
                  "scene's force at --force-index");
  cmd->add_option("--param,-p", args->params, "parameter for the instances, key=value (repeat)");
  cmd->add_option("--params", args->params_json, "parameters as a JSON object");
  cmd->add_option("--seed", args->seed, "random seed for the states");
  cmd->add_option("--trials", args->trials, "random states per check")->check(CLI::Range(1, 1000));
  cmd->add_flag("--assume-internal", args->assume_internal,
                "run the internal-force checks even if the plugin does not declare INTERNAL");
  cmd->add_flag("--json", args->json, "print the report as JSON");
  cmd->add_flag("--strict", args->strict,
                "fail (exit 1) when a check is skipped, as the grader does where it scores it");
  cmd->add_option("--rubric", args->rubric,
                  "a grading rubric (path, or name of a shipped one): name its tests of this "
                  "plugin that score a check skipped here, and fail on them");
  cmd->add_option("--topology", args->topology,
                  "elements the random states carry: chain (random points, an open chain; "
                  "default for a fixed arity), ring (a closed ring; default for whole-body "
                  "plugins), grid (a grid blob), body (two bodies, every element set)")
      ->check(CLI::IsMember(check_topologies()));
  cmd->add_option("--scene", args->scene,
                  "check on a scene's own force: its elements, parameters (-p overrides them) "
                  "and states around its initial state");
  cmd->add_option("--force-index", args->force_index,
                  "with --scene: which entry of the scene's \"forces\" (default 0)");
  cmd->add_option("--plugin-path", args->plugin_path,
                  "folder searched first for a plugin given by name (repeat); otherwise "
                  "$PINSIM_PLUGIN_PATH, the install and the build tree are searched");
  cmd->callback([args] {
    const int code = run_check_plugin(*args);
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace pinsim::cli
