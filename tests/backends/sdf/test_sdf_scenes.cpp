// The shipped scenes: they load, the grid gives the same distances as brute force, and
// the pinball ball stays on the table.
#include <random>
#include <set>

#include "sdf_harness.hpp"

using namespace pinsim;
using namespace pinsim::sdf;
using namespace pinsim::sdf::test;
using nlohmann::json;

TEST_CASE("grid queries equal brute-force queries on the pinball table") {
  const json scene = load_config("pinball.json");
  Sim grid(backend_scene(scene), {}, scene["backend"]["params"]);
  json nogrid_params = scene["backend"]["params"];
  nogrid_params["grid_cells"] = 0;
  Sim brute(backend_scene(scene), {}, nogrid_params);
  CHECK(grid.backend->field().grid_stats().first > 1000);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> ux(-0.1, 0.7), uy(-0.1, 1.2), ut(0.0, 4.0);
  for (int k = 0; k < 20000; ++k) {
    const Vec2 p(ux(rng), uy(rng));
    const double t = ut(rng);
    int64_t a = -2, b = -2;
    const double da = grid.backend->distance(p, t, &a), db = brute.backend->distance(p, t, &b);
    REQUIRE(da == db);
  }
}

TEST_CASE("grid queries equal brute force to the bit with booleans, flippers and sliders") {
  // The grid stores each static obstacle's tree reduced to the operand that decides it
  // over a cell, and moving obstacles' bounds over all their poses: distances, obstacle
  // and gradient must be those of the full trees.
  const json circ = {{"type", "circle"}, {"center", {0.3, 0.3}}, {"radius", 0.12}};
  const json box = {{"type", "box"}, {"center", {0.4, 0.3}}, {"half_size", {0.1, 0.05}}};
  const json cap = {{"type", "capsule"}, {"a", {0.2, 0.6}}, {"b", {0.5, 0.7}}, {"radius", 0.03}};
  const json scene = {
      {"obstacles",
       {obstacle("walls", {{"type", "inside"},
                           {"shape",
                            {{"type", "union"},
                             {"shapes",
                              {{{"type", "box"}, {"center", {0.5, 0.5}}, {"half_size", {0.5, 0.4}}},
                               {{"type", "circle"}, {"center", {0.5, 0.9}}, {"radius", 0.5}}}}}}}),
        obstacle("sub", {{"type", "subtraction"}, {"shapes", {circ, box}}}),
        obstacle(
            "inter",
            {{"type", "intersection"},
             {"shapes", {cap, {{"type", "circle"}, {"center", {0.35, 0.65}}, {"radius", 0.12}}}}}),
        obstacle("moved", {{"type", "union"},
                           {"shapes", {box, cap}},
                           {"transform", {{"translate", {0.3, 0.1}}, {"rotate", 0.5}}}}),
        obstacle("tri", {{"type", "polygon"}, {"points", {{0.7, 0.2}, {0.9, 0.25}, {0.75, 0.4}}}}),
        obstacle("rounded", {{"type", "rounded_box"},
                             {"center", {0.6, 1.0}},
                             {"half_size", {0.08, 0.05}},
                             {"angle", 0.3},
                             {"corner_radius", 0.02}}),
        obstacle("peg",
                 {{"type", "capsule"}, {"a", {0.15, 1.1}}, {"b", {0.3, 1.2}}, {"radius", 0.02}}),
        {{"id", "flipper"},
         {"shape",
          {{"type", "tapered_capsule"},
           {"a", {0, 0}},
           {"b", {0.15, 0}},
           {"radius_a", 0.02},
           {"radius_b", 0.01}}},
         {"motion",
          {{"type", "flipper"},
           {"pivot", {0.2, 0.2}},
           {"rest_angle", -0.5},
           {"raised_angle", 0.5},
           {"angular_speed", 20.0},
           {"input", "f"}}}},
        {{"id", "slider"},
         {"shape", {{"type", "box"}, {"center", {0.8, 0.7}}, {"half_size", {0.03, 0.03}}}},
         {"motion",
          {{"type", "slider"}, {"offset", {0.0, -0.2}}, {"speed", 1.0}, {"input", "s"}}}}}},
      {"inputs",
       {{{"t", 0.1}, {"input", "f"}, {"action", "press"}},
        {{"t", 0.3}, {"input", "f"}, {"action", "release"}},
        {{"t", 0.2}, {"input", "s"}, {"action", "press"}},
        {{"t", 0.5}, {"input", "s"}, {"action", "release"}}}}};
  Sim grid(scene, {}, {{"grid_cells", 4096}});
  Sim brute(scene, {}, {{"grid_cells", 0}});
  REQUIRE(grid.backend->field().grid_stats().first > 1000);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> ux(-0.05, 1.05), uy(-0.05, 1.45), ut(0.0, 1.0);
  for (int n = 0; n < 100000; ++n) {
    const Vec2 p(ux(rng), uy(rng));
    const double t = ut(rng);
    const Nearest a = grid.backend->field().nearest_with_gradient(p, t);
    const Nearest b = brute.backend->field().nearest_with_gradient(p, t);
    INFO("p = (" << p.x() << ", " << p.y() << "), t = " << t);
    REQUIRE(a.d == b.d);
    REQUIRE(a.k == b.k);
    REQUIRE(a.g.x() == b.g.x());
    REQUIRE(a.g.y() == b.g.y());
    const Nearest c = grid.backend->field().nearest(p, t);
    REQUIRE(c.d == b.d);
    REQUIRE(c.k == b.k);
  }
}

TEST_CASE("the pinball ball stays on the table and hits things") {
  const json scene = load_config("pinball.json");
  std::vector<Ball> balls;
  for (const auto& p : scene["particles"])
    balls.push_back({Vec2(p["x"][0], p["x"][1]), Vec2(p["v"][0], p["v"][1]),
                     p["radius"].get<double>(), 1.0 / p["mass"].get<double>()});
  Sim sim(backend_scene(scene), balls, scene["backend"]["params"]);
  const double dt = scene["time"]["dt"], T = scene["time"]["duration"];
  const Vec2 g(scene["forces"][0]["params"]["g"][0], scene["forces"][0]["params"]["g"][1]);
  const int steps = static_cast<int>(std::lround(T / dt));
  double min_clear = HUGE_VAL;
  for (int n = 0; n < steps; ++n) {
    sim.step(dt, g);
    for (std::size_t i = 0; i < balls.size(); ++i) {
      const double d = sim.backend->distance(sim.pos(i), sim.t, nullptr) - sim.r[i];
      min_clear = std::min(min_clear, d);
    }
  }
  CHECK(min_clear > -sim.backend->depth_min());
  CHECK(sim.events.size() > 10);
  std::set<int64_t> hit;
  for (const auto& e : sim.events) hit.insert(e.obstacle);
  CHECK(hit.size() >= 4);
}

TEST_CASE("the empty box scene is the seed's 1D problem") {
  const json scene = load_config("empty_box.json");
  REQUIRE(scene["particles"].size() == 1);
  Sim sim(backend_scene(scene),
          {{Vec2(scene["particles"][0]["x"][0], scene["particles"][0]["x"][1]),
            Vec2(scene["particles"][0]["v"][0], scene["particles"][0]["v"][1]),
            scene["particles"][0]["radius"].get<double>()}},
          scene["backend"]["params"]);
  const double v0 = scene["particles"][0]["v"][0];
  for (int n = 0; n < 1000; ++n) sim.step(scene["time"]["dt"].get<double>());
  CHECK(std::abs(sim.vel().x()) == std::abs(v0));
  CHECK(sim.vel().y() == 0.0);
  CHECK(!sim.events.empty());
}

TEST_CASE("the pinball run is deterministic: two runs agree to the bit") {
  const json scene = load_config("pinball.json");
  auto run = [&] {
    const auto& p = scene["particles"][0];
    Sim sim(backend_scene(scene),
            {{Vec2(p["x"][0], p["x"][1]), Vec2(p["v"][0], p["v"][1]), p["radius"].get<double>(),
              1.0 / p["mass"].get<double>()}},
            scene["backend"]["params"]);
    for (int n = 0; n < 20000; ++n) sim.step(scene["time"]["dt"].get<double>(), Vec2(0, -1.11));
    return std::make_pair(sim.x, sim.v);
  };
  const auto a = run(), b = run();
  CHECK(a.first == b.first);
  CHECK(a.second == b.second);
}
