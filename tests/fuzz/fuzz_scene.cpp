// Fuzz entries for scenes and --set: parsing and validation up to creating plugin instances.
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "core/param_validation.hpp"
#include "core/scene.hpp"
#include "fuzz_guard.hpp"
#include "tools/crosscheck.hpp"

namespace pinsim::fuzz {
namespace {

namespace fs = std::filesystem;

/// The build tree's plugins by name, loaded once: only their tables are used.
const LoadedPlugin* shipped(const std::string& name) {
  static const auto plugins = [] {
    std::map<std::string, std::shared_ptr<const LoadedPlugin>> m;
    const PluginLoader loader({PINSIM_BUILD_PLUGIN_DIR});
    for (const auto& l : loader.list())
      if (l.plugin) m.emplace(l.plugin->name(), l.plugin);
    return m;
  }();
  const auto it = plugins.find(name);
  return it == plugins.end() ? nullptr : it->second.get();
}

/// What `validate` checks of a parsed scene before it creates instances: each plugin's
/// kind, parameters and elements (as create_force and create_backend do), the initial
/// state, the crosscheck spec. A plugin that is not shipped, or named by a library file,
/// is skipped: the fuzzer loads no file an input names.
void check_scene(const Scene& s) {
  for (const ForceSpec& f : s.forces) {
    const LoadedPlugin* p = f.library.empty() ? shipped(f.name) : nullptr;
    if (p == nullptr) continue;
    if (p->table->kind != PINSIM_KIND_FORCE)
      throw SceneError(f.where + ".type: plugin '" + f.name + "' is a backend, not a force");
    validate_params(*p->table, f.params, f.where + ".params");
    s.resolve_elements(f, p->table->arity);
  }
  if (const LoadedPlugin* p = s.backend.library.empty() ? shipped(s.backend.name) : nullptr) {
    if (p->table->kind != PINSIM_KIND_BACKEND)
      throw SceneError(s.backend.where + ": plugin '" + s.backend.name +
                       "' is a force, not a backend");
    validate_params(*p->table, s.backend.params, s.backend.where + ".params");
  }
  (void)s.initial_state();
  (void)s.steps();
  (void)parse_crosscheck(s);
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

Result scene(std::string_view bytes) {
  return guarded([&] { check_scene(parse_scene(std::string(bytes), "fuzz.json", configs_dir())); });
}

Result set(std::string_view bytes) {
  static const std::string base = read_text(configs_dir() / "pinball.json");
  std::vector<std::string> overrides;
  std::size_t start = 0;
  while (start < bytes.size()) {
    std::size_t end = bytes.find('\n', start);
    if (end == std::string_view::npos) end = bytes.size();
    overrides.emplace_back(bytes.substr(start, end - start));
    start = end + 1;
  }
  return guarded([&] { check_scene(parse_scene(base, "pinball.json", configs_dir(), overrides)); });
}

Entry entry(std::string_view name) {
  if (name == "scene") return scene;
  if (name == "set") return set;
  if (name == "sweep_config") return sweep_config;
  if (name == "rubric") return rubric;
  return nullptr;
}

}  // namespace pinsim::fuzz
