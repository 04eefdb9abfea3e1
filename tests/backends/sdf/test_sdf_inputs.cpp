// Live inputs: a press or release between steps (SdfBackend::input) gives the same motion,
// to the bit, as a backend created with the event already in its scene's "inputs".
#include <catch2/catch.hpp>
#include <cmath>

#include "sdf_harness.hpp"

using namespace pinsim;
using namespace pinsim::sdf;
using namespace pinsim::sdf::test;
using Catch::Matchers::Contains;
using nlohmann::json;

TEST_CASE("timeline: events appended one by one equal the whole list at construction") {
  const std::vector<std::pair<double, bool>> evs = {{0.0, true},   {0.01, false}, {0.05, true},
                                                    {0.05, false}, {0.2, true},   {0.3, false}};
  Timeline grown(3.6416, 2.6916, 25.0, 10.0, {});
  for (const auto& [t, press] : evs) grown.add_event(t, press);
  const Timeline whole(3.6416, 2.6916, 25.0, 10.0, evs);
  CHECK(grown.events() == evs);
  for (int k = 0; k <= 500; ++k) {
    const double t = 0.001 * k;
    CAPTURE(t);
    double c1 = 0, s1 = 0, c2 = 0, s2 = 0;
    REQUIRE(grown.value_cos_sin(t, c1, s1) == whole.value_cos_sin(t, c2, s2));
    REQUIRE((c1 == c2 && s1 == s2));
    REQUIRE(grown.rate(t) == whole.rate(t));
  }
}

TEST_CASE("sdf input: live presses equal a backend rebuilt with the grown inputs list") {
  // What `pinsim play` did before live inputs: on every press, a new backend whose scene
  // lists every event so far. The live backend must give the identical states.
  json scene = backend_scene(load_config("pinball.json"));
  const json script = scene["inputs"];
  scene.erase("inputs");
  const json full = load_config("pinball.json");
  const auto& p = full["particles"][0];
  const std::vector<Ball> balls = {{Vec2(p["x"][0], p["x"][1]), Vec2(p["v"][0], p["v"][1]),
                                    p["radius"].get<double>(), 1.0 / p["mass"].get<double>()}};
  const json par = full["backend"]["params"];
  const double dt = full["time"]["dt"];
  const Vec2 g(0.0, -1.11);
  Sim live(scene, balls, par), rebuilt(scene, balls, par);
  json grown = json::array();
  std::size_t next = 0;
  const int steps = 25000;  // 5 s: every scripted press and release up to then
  for (int n = 0; n < steps; ++n) {
    while (next < script.size() &&
           std::lround(script[next]["t"].get<double>() / dt) <= static_cast<long>(n)) {
      const std::string in = script[next]["input"];
      const bool press = script[next]["action"] == "press";
      live.backend->input(in, press, live.t);
      grown.push_back({{"t", rebuilt.t}, {"input", in}, {"action", press ? "press" : "release"}});
      json s = scene;
      s["inputs"] = grown;
      Sim fresh(s, balls, par);  // its backend, created from the initial balls
      rebuilt.backend = std::move(fresh.backend);
      ++next;
    }
    live.step(dt, g);
    rebuilt.step(dt, g);
    CAPTURE(n);
    REQUIRE(live.x == rebuilt.x);
    REQUIRE(live.v == rebuilt.v);
  }
  CHECK(next >= 10);
  CHECK(live.events.size() == rebuilt.events.size());
}

TEST_CASE("sdf input: an unknown input or an event back in time is an error naming it") {
  json scene = backend_scene(load_config("pinball.json"));
  scene.erase("inputs");
  Sim sim(scene, {{Vec2(0.4745, 0.0436), Vec2(0, 0), 0.0135}});
  REQUIRE_THROWS_WITH(sim.backend->input("nudge", true, 0.0),
                      Contains("\"nudge\"") && Contains("no obstacle's motion listens to it"));
  sim.backend->input("left", true, 0.5);
  REQUIRE_THROWS_WITH(sim.backend->input("left", false, 0.25),
                      Contains("\"left\"") && Contains("time order"));
}
