// The static plugin registry (core/static_plugins.hpp): plugins linked into the program run
// the pinball table to the same state, bit for bit, as the same plugins loaded from their
// libraries (the web engine relies on this registry; issue 17).
#include "core/static_plugins.hpp"

#include <catch2/catch.hpp>
#include <filesystem>

#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"

using namespace pinsim;
namespace fs = std::filesystem;

namespace {
struct Run {
  uint64_t hash = 0;
  std::size_t contacts = 0;
  std::vector<std::string> paths;
};

Run run(const Scene& scene, PluginLoader& loader, int steps) {
  Simulation sim(scene, loader);
  Run r;
  for (int i = 0; i < steps; ++i) {
    sim.step();
    r.contacts += sim.events().size();
  }
  r.hash = sim.state().hash();
  for (const auto& name : loader.loaded()) r.paths.push_back(loader.load(name)->path.string());
  return r;
}
}  // namespace

TEST_CASE("static plugins: the in-tree plugins are registered") {
  for (const char* name : {"sdf", "none", "gravity", "linear_spring", "damped_spring", "bending"})
    CHECK(find_static_plugin(name) != nullptr);
  CHECK(find_static_plugin("no_such_plugin") == nullptr);
  // A second registration of a name is refused.
  CHECK_FALSE(register_static_plugin("sdf", find_static_plugin("sdf")->entry));
}

TEST_CASE("static plugins: the pinball table runs bit-identically to the plugin libraries") {
  const Scene scene = load_scene(fs::path(PINSIM_SOURCE_DIR) / "configs/pinball.json");
  const int steps = 15000;  // 3 s: plunger shot, lane, bumpers (the scene's script)

  PluginLoader builtin({});  // no search directories: only the registry can answer
  const Run a = run(scene, builtin, steps);
  for (const auto& p : a.paths) CHECK(p.rfind("(built in)/", 0) == 0);

  // The same plugins from their .so files, provided ahead of the registry.
  PluginLoader libs(plugin_search_dirs());
  for (const char* name : {"sdf", "gravity"})
    libs.provide(load_plugin_file(fs::path(PINSIM_BUILD_PLUGIN_DIR) / plugin_file_name(name)));
  const Run b = run(scene, libs, steps);
  for (const auto& p : b.paths) CHECK(p.find("(built in)") == std::string::npos);

  CHECK(a.contacts > 0);
  CHECK(a.contacts == b.contacts);
  CHECK(a.hash == b.hash);
}
