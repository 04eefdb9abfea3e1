// Each plugin-loading failure gives its own clear message.
#include <catch2/catch.hpp>
#include <filesystem>

#include "core/plugin_instance.hpp"
#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;
namespace fs = std::filesystem;

namespace {
const fs::path fixtures = PINSIM_TEST_FIXTURE_DIR;
}

TEST_CASE("loader: finds and loads an in-tree plugin by name") {
  PluginLoader loader(plugin_search_dirs());
  auto p = loader.load("gravity");
  CHECK(p->name() == "gravity");
  CHECK(p->is_force());
  CHECK(p->table->abi_version == PINSIM_ABI_VERSION);
  // Loading again returns the same library.
  CHECK(loader.load("gravity").get() == p.get());
}

TEST_CASE("loader: file not found") {
  REQUIRE_THROWS_WITH(load_plugin_file(fixtures / "libno_such_file.so"),
                      Contains("plugin file not found") && Contains("libno_such_file.so"));
}

TEST_CASE("loader: unknown plugin name lists the searched folders") {
  PluginLoader loader({fixtures});
  REQUIRE_THROWS_WITH(loader.load("no_such_plugin"),
                      Contains("unknown plugin 'no_such_plugin'") &&
                          Contains("libpinsim_plugin_no_such_plugin.so") &&
                          Contains(fixtures.string()));
}

TEST_CASE("loader: a file that is not a shared library is not a pinsim plugin") {
  REQUIRE_THROWS_WITH(load_plugin_file(fixtures / "libfixture_not_a_library.so"),
                      Contains("not a pinsim plugin") && Contains("libfixture_not_a_library.so"));
}

TEST_CASE("loader: a shared library without the entry symbol") {
  REQUIRE_THROWS_WITH(load_plugin_file(fixtures / "libfixture_no_entry.so"),
                      Contains("missing symbol 'pinsim_plugin_entry'"));
}

TEST_CASE("loader: wrong ABI version names both versions") {
  REQUIRE_THROWS_WITH(load_plugin_file(fixtures / "libfixture_wrong_abi.so"),
                      Contains("wrong plugin ABI version") &&
                          Contains("plugin has " + std::to_string(PINSIM_ABI_VERSION + 41)) &&
                          Contains("expects " + std::to_string(PINSIM_ABI_VERSION)));
}

TEST_CASE("loader: a plugin built against ABI 1 (no backend input()) is refused") {
  static_assert(PINSIM_ABI_VERSION == 4);
  REQUIRE_THROWS_WITH(load_plugin_file(fixtures / "libfixture_abi_v1.so"),
                      Contains("wrong plugin ABI version") && Contains("plugin has 1,") &&
                          Contains("expects 4") && Contains("rebuild it against this SDK"));
}

TEST_CASE("loader: a plugin built against ABI 2 (no backend outline()) is refused") {
  REQUIRE_THROWS_WITH(load_plugin_file(fixtures / "libfixture_abi_v2.so"),
                      Contains("wrong plugin ABI version") && Contains("plugin has 2,") &&
                          Contains("expects 4") && Contains("rebuild it against this SDK"));
}

TEST_CASE("loader: two libraries declaring one plugin name") {
  PluginLoader loader({});
  loader.load_path(fixtures / "libfixture_dup_a.so", "dup");
  REQUIRE_THROWS_WITH(loader.load_path(fixtures / "libfixture_dup_b.so", "dup"),
                      Contains("two plugins named 'dup'") && Contains("libfixture_dup_a.so") &&
                          Contains("libfixture_dup_b.so"));
}

TEST_CASE("loader: a library whose declared name differs from the requested one") {
  PluginLoader loader({});
  REQUIRE_THROWS_WITH(loader.load_path(fixtures / "libfixture_dup_a.so", "gravity"),
                      Contains("declares plugin 'dup', expected 'gravity'"));
}

TEST_CASE("loader: a scene's plugin_path is searched first") {
  // The fixture folder holds no libpinsim_plugin_gravity.so, so gravity still comes from the
  // build tree, after the scene's folder.
  const auto dirs = plugin_search_dirs({fixtures});
  REQUIRE(dirs.size() >= 3);
  CHECK(dirs.front() == fixtures);
  CHECK(dirs[dirs.size() - 2] == fs::path(PINSIM_BUILD_PLUGIN_DIR));
}

TEST_CASE("loader: instances keep their library alive after the loader is gone") {
  const std::string text = R"({"time": {"dt": 0.1, "duration": 0.2},
    "particles": [{"x": [0, 0]}], "forces": [{"type": "gravity"}]})";
  const Scene scene = parse_scene(text, "keep.json", ".");
  std::unique_ptr<Simulation> sim;
  {
    PluginLoader loader(plugin_search_dirs());
    sim = std::make_unique<Simulation>(scene, loader);
  }
  sim->step();
  CHECK(sim->state().v(1, 0) == Approx(-0.981));
}

TEST_CASE("loader: a run loads only the plugins its scene names") {
  const std::string text = R"({"time": {"dt": 0.1, "duration": 0.2},
    "particles": [{"x": [0, 0]}], "forces": [{"type": "gravity"}]})";
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(parse_scene(text, "only.json", "."), loader);
  CHECK(loader.loaded() == std::vector<std::string>{"gravity", "none"});
}
