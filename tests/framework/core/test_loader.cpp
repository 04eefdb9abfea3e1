// Each plugin-loading failure gives its own clear message.
#include <catch2/catch.hpp>
#include <filesystem>

#include "core/plugin_instance.hpp"
#include "core/plugin_loader.hpp"
#include "core/plugin_table_check.hpp"
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
  // a bigger major: the plugin was built for a newer pinsim
  REQUIRE_THROWS_WITH(load_plugin_file(fixtures / "libfixture_wrong_abi.so"),
                      Contains("libfixture_wrong_abi.so") && Contains("wrong plugin ABI version") &&
                          Contains("plugin has " + std::to_string(PINSIM_ABI_VERSION + 41)) &&
                          Contains("expects " + std::to_string(PINSIM_ABI_VERSION)) &&
                          Contains("this pinsim has ABI 4.5") && Contains("newer pinsim"));
}

TEST_CASE("loader: a plugin built against the previous minor (4.0) loads and runs") {
  static_assert(PINSIM_ABI_MAJOR == 4 && PINSIM_ABI_MINOR == 5);
  // The C fixture's table is the 4.0 layout, which ends before abi_minor; the word after it
  // holds 0xdeadbeef, so a loader reading past struct_size would refuse it as ABI 4.3735928559.
  auto p = load_plugin_file(fixtures / "libpinsim_plugin_abi40_push.so");
  CHECK(p->name() == "abi40_push");
  CHECK(p->table->struct_size == PINSIM_ABI_MIN_TABLE_SIZE);
  CHECK(p->table->abi_minor == 0);  // absent
  CHECK_FALSE(PINSIM_TABLE_HAS(p->table, abi_minor));
  CHECK(table_version(*p->table).major == 4);
  CHECK(table_version(*p->table).minor == 0);

  // It runs: a constant force F = (2, -3) on a particle of mass m = 2, symplectic Euler
  // with step h: v_n = v0 + n h F/m, x_n = x0 + n h v0 + h^2 (F/m) n (n + 1) / 2.
  const std::string text = R"({"plugin_path": [")" + fixtures.string() + R"("],
    "time": {"dt": 0.01, "duration": 1.0}, "integrator": "symplectic_euler",
    "particles": [{"x": [1, 1], "v": [0.5, 0], "mass": 2}],
    "forces": [{"type": "abi40_push"}]})";
  const Scene scene = parse_scene(text, "abi40.json", ".");
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  Simulation sim(scene, loader);
  const int n = 50;
  for (int k = 0; k < n; ++k) sim.step();
  const double h = 0.01, ax = 2.0 / 2.0, ay = -3.0 / 2.0;
  const double c = h * h * n * (n + 1) / 2.0;
  CHECK(sim.state().v(0, 0) == Approx(0.5 + n * h * ax).epsilon(1e-12));
  CHECK(sim.state().v(1, 0) == Approx(n * h * ay).epsilon(1e-12));
  CHECK(sim.state().x(0, 0) == Approx(1.0 + n * h * 0.5 + c * ax).epsilon(1e-12));
  CHECK(sim.state().x(1, 0) == Approx(1.0 + c * ay).epsilon(1e-12));
  // its energy() is called too: E = -F.x
  CHECK(sim.potential_energy(sim.state()) ==
        Approx(-(2.0 * sim.state().x(0, 0) - 3.0 * sim.state().x(1, 0))).epsilon(1e-12));
}

TEST_CASE("loader: a table shorter than the smallest of its major is refused") {
  REQUIRE_THROWS_WITH(
      load_plugin_file(fixtures / "libfixture_abi_short.so"),
      Contains("libfixture_abi_short.so") && Contains("wrong plugin table size") &&
          Contains("plugin has ABI 4 and a table of " +
                   std::to_string(PINSIM_ABI_MIN_TABLE_SIZE - sizeof(void*)) + " bytes") &&
          Contains(std::to_string(PINSIM_ABI_MIN_TABLE_SIZE) + " bytes") &&
          Contains("this pinsim has ABI 4.5") && Contains("rebuild it against this SDK"));
}

TEST_CASE("loader: a plugin built against a newer minor is refused") {
  REQUIRE_THROWS_WITH(load_plugin_file(fixtures / "libfixture_abi_newer_minor.so"),
                      Contains("libfixture_abi_newer_minor.so") &&
                          Contains("plugin built against ABI 4.6, newer than this pinsim's 4.5") &&
                          Contains("run it with a pinsim of ABI 4.6 or later"));
}

TEST_CASE("loader: a plugin built against 4.1 loads without the 4.2 constraint entries") {
  // The fixture's 4.1 table is followed by 0xdeadbeef words where a 4.2 table keeps
  // constraint_set and constraints: the host's copy must hold them as absent.
  auto p = load_plugin_file(fixtures / "libpinsim_plugin_abi41_push.so");
  CHECK(p->name() == "abi41_push");
  CHECK(table_version(*p->table).minor == 1);
  CHECK(p->table->constraint_set == nullptr);
  CHECK(p->table->constraints == nullptr);
  // It runs under xpbd as an external force: a constant force F = (2, -3) on a free particle
  // of mass 2, so with no constraints xpbd is symplectic Euler (x_n as in the 4.0 test).
  const std::string text = R"({"plugin_path": [")" + fixtures.string() + R"("],
    "time": {"dt": 0.01, "duration": 1.0}, "integrator": "xpbd",
    "particles": [{"x": [1, 1], "v": [0.5, 0], "mass": 2}],
    "forces": [{"type": "abi41_push"}]})";
  const Scene scene = parse_scene(text, "abi41.json", ".");
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  Simulation sim(scene, loader);
  const int n = 50;
  for (int k = 0; k < n; ++k) sim.step();
  const double h = 0.01, ay = -3.0 / 2.0, c = h * h * n * (n + 1) / 2.0;
  CHECK(sim.state().x(1, 0) == Approx(1.0 + c * ay).epsilon(1e-12));
  CHECK(sim.integrator_stats()["external_forces"][0] == "forces[0] 'abi41_push'");
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
