// `pinsim check-plugin NAME|PATH`: the physics check of a force plugin (plugin_check.hpp).
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "core/plugin_loader.hpp"
#include "core/scene_error.hpp"
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
};

nlohmann::json parse_params(const CheckPluginArgs& a) {
  nlohmann::json p = nlohmann::json::object();
  if (!a.params_json.empty()) {
    p = nlohmann::json::parse(a.params_json, nullptr, false);
    if (!p.is_object()) throw SceneError("--params: expected a JSON object, got " + a.params_json);
  }
  for (const auto& kv : a.params) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos || eq == 0)
      throw SceneError("--param " + kv + ": expected key=value");
    const std::string key = kv.substr(0, eq), value = kv.substr(eq + 1);
    nlohmann::json v = nlohmann::json::parse(value, nullptr, false);
    p[key] = v.is_discarded() ? nlohmann::json(value) : v;
  }
  return p;
}

int run_check_plugin(const CheckPluginArgs& a) {
  try {
    std::shared_ptr<const LoadedPlugin> plugin;
    PluginLoader loader(plugin_search_dirs());
    const bool is_path = a.plugin.find('/') != std::string::npos ||
                         (a.plugin.size() > 3 && a.plugin.substr(a.plugin.size() - 3) == ".so");
    plugin = is_path ? loader.load_path(a.plugin, "") : loader.load(a.plugin);
    CheckOptions opt;
    opt.params = parse_params(a);
    opt.seed = a.seed;
    opt.trials = a.trials;
    opt.assume_internal = a.assume_internal;
    const CheckReport rep = check_force_plugin(*plugin, opt);
    if (a.json)
      std::cout << report_json(rep).dump(2) << "\n";
    else
      std::cout << format_report(rep);
    return rep.passed() ? 0 : 1;
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
  cmd->add_option("plugin", args->plugin, "plugin name (searched) or path to a .so file")
      ->required();
  cmd->add_option("--param,-p", args->params, "parameter for the instances, key=value (repeat)");
  cmd->add_option("--params", args->params_json, "parameters as a JSON object");
  cmd->add_option("--seed", args->seed, "random seed for the states");
  cmd->add_option("--trials", args->trials, "random states per check")->check(CLI::Range(1, 1000));
  cmd->add_flag("--assume-internal", args->assume_internal,
                "run the internal-force checks even if the plugin does not declare INTERNAL");
  cmd->add_flag("--json", args->json, "print the report as JSON");
  cmd->callback([args] {
    const int code = run_check_plugin(*args);
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace pinsim::cli
