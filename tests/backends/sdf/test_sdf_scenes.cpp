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
