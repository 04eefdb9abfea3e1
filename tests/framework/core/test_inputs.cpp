// Live inputs through the one step path: Simulation::set_input between steps reaches the
// backend's input() at the state time; a backend without it is refused by name.
#include <catch2/catch.hpp>

#include "core/plugin_instance.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;

TEST_CASE("set_input: a press between steps moves the flipper from the state time") {
  Scene scene = load_scene(PINSIM_SOURCE_DIR "/configs/pinball.json");
  scene.backend_scene.erase("inputs");
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(scene, loader);
  REQUIRE(sim.backend().has_input());
  // The left flipper (pivot (0.12, 0.10), 0.075 long) raised to 0.45 rad has its tip at
  // (0.187, 0.133); a press at t = 0.1 s raises it at 25 rad/s from -0.5 rad: 0.038 s.
  for (int n = 0; n < 500; ++n) sim.step();
  int64_t k = -1;
  const double before = sim.backend().distance(0.187, 0.133, sim.state().t, &k);
  sim.set_input("left", true);
  for (int n = 0; n < 250; ++n) sim.step();
  const double after = sim.backend().distance(0.187, 0.133, sim.state().t, &k);
  CHECK(after < 0.0);
  CHECK(before > after);
  REQUIRE_THROWS_WITH(sim.set_input("nudge", true),
                      Contains("\"nudge\"") && Contains("no obstacle's motion listens"));
}

TEST_CASE("set_input: a backend without live inputs says so") {
  const Scene scene = load_scene(PINSIM_SOURCE_DIR "/configs/projectile.json");
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(scene, loader);
  CHECK_FALSE(sim.backend().has_input());
  REQUIRE_THROWS_WITH(sim.set_input("left", true), Contains("backend 'none'") &&
                                                       Contains("does not take live inputs") &&
                                                       Contains("\"left\""));
}
