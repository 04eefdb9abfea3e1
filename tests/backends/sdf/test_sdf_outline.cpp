// The sdf backend's outline(): rings on the exact boundary (vertices on it, chords within
// the tolerance), bounds of the shipped tables, the sweep of moving obstacles and the clip
// of half-planes.
#include <algorithm>
#include <cmath>

#include "sdf_harness.hpp"

using namespace pinsim;
using namespace pinsim::sdf;
using namespace pinsim::sdf::test;
using nlohmann::json;

namespace {

/// Every vertex of every ring and every chord's midpoint lies within `tol` of obstacle k's
/// boundary at time t (inside or out): vertices of a primitive lie on it, those where two
/// parts' rings cross on the chords.
void check_on_boundary(const ObstacleField& f, std::size_t k, const ObstacleOutline& o, double t,
                       double tol) {
  INFO("obstacle " << o.id);
  REQUIRE(!o.rings.empty());
  for (const auto& ring : o.rings) {
    REQUIRE(ring.size() >= 2);
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const Vec2 a = ring[i], b = ring[(i + 1) % ring.size()];
      CHECK(std::abs(f.eval(k, a, t).d) <= tol + 1e-9);
      CHECK(std::abs(f.eval(k, 0.5 * (a + b), t).d) <= tol + 1e-9);
    }
  }
}

}  // namespace

TEST_CASE("outline: every obstacle of the shipped scenes lies on its boundary") {
  for (const char* file : {"pinball.json", "blob_obstacles.json", "empty_box.json"}) {
    INFO(file);
    Sim sim(backend_scene(load_config(file)), {{Vec2(0.2, 0.3), Vec2::Zero()}});
    const ObstacleField& f = sim.backend->field();
    const double tol = 1e-4;
    pinsim_state_view sv{1, 0.0, sim.x.data(), sim.v.data(), sim.w.data(), sim.r.data()};
    const OutlineSet set = sim.backend->outline(StateView(sv), tol);
    REQUIRE(set.obstacles.size() == f.size());
    for (std::size_t k = 0; k < f.size(); ++k) {
      CHECK(set.obstacles[k].obstacle == static_cast<int64_t>(k));
      CHECK(set.obstacles[k].id == f.obstacle(k).id);
      check_on_boundary(f, k, set.obstacles[k], 0.0, tol);
    }
  }
}

TEST_CASE("outline: the pinball table's bounds are its outer wall's, exactly") {
  Sim sim(backend_scene(load_config("pinball.json")), {{Vec2(0.2, 0.3), Vec2::Zero()}});
  pinsim_state_view sv{1, 0.0, sim.x.data(), sim.v.data(), sim.w.data(), sim.r.data()};
  const OutlineSet set = sim.backend->outline(StateView(sv), 0.0);
  // the outer wall's box (x 0..0.5, y -0.05..0.75) under a circle of radius 0.25 about
  // (0.25, 0.75); the drain (0.22 +- 0.225, -0.04 +- 0.01) sticks out on the left
  CHECK(set.sweep.x0 == 0.22 - 0.225);
  CHECK(set.sweep.x1 == 0.25 + 0.25);
  CHECK(set.sweep.y0 == std::min(0.35 - 0.4, -0.04 - 0.01));
  CHECK(set.sweep.y1 == 0.75 + 0.25);
  CHECK(set.bounds.y1 == set.sweep.y1);
  CHECK(set.obstacles[0].bounds.x0 == 0.25 - 0.25);
  // the outer wall is one ring: the inside of the box-and-circle union, clockwise
  REQUIRE(set.obstacles[0].rings.size() == 1);
  double area2 = 0.0;
  const auto& r = set.obstacles[0].rings[0];
  for (std::size_t i = 0; i < r.size(); ++i) {
    const Vec2 a = r[i], b = r[(i + 1) % r.size()];
    area2 += a.x() * b.y() - a.y() * b.x();
  }
  CHECK(area2 < 0.0);
}

TEST_CASE("outline: a flipper's sweep holds every pose, its bounds follow the time") {
  json scene = backend_scene(load_config("pinball.json"));
  scene["inputs"] = json::array({{{"t", 0.0}, {"input", "left"}, {"action", "press"}}});
  Sim sim(scene, {{Vec2(0.2, 0.3), Vec2::Zero()}});
  const ObstacleField& f = sim.backend->field();
  std::size_t k = 0;
  while (f.obstacle(k).id != "flipper_left") ++k;
  const Ring clip = f.outline_clip({});
  const ObstacleField::Outline rest = f.outline(k, 0.0, 1e-4, clip);
  for (const double t : {0.0, 0.01, 0.02, 0.03, 0.2}) {
    const ObstacleField::Outline o = f.outline(k, t, 1e-4, clip);
    CHECK(o.sweep.lo == rest.sweep.lo);
    CHECK(o.sweep.hi == rest.sweep.hi);
    CHECK(o.bounds.lo.x() >= o.sweep.lo.x());
    CHECK(o.bounds.lo.y() >= o.sweep.lo.y());
    CHECK(o.bounds.hi.x() <= o.sweep.hi.x());
    CHECK(o.bounds.hi.y() <= o.sweep.hi.y());
    for (const Ring& r : o.rings)
      for (const Vec2& p : r) CHECK(std::abs(f.eval(k, p, t).d) <= 1e-9);
  }
  // raised by t = 0.2: the tip is higher than at rest
  CHECK(f.outline(k, 0.2, 1e-4, clip).bounds.hi.y() > rest.bounds.hi.y() + 0.01);
}

TEST_CASE("outline: a half-plane is cut to the obstacles and particles, grown by a tenth") {
  const json scene = {
      {"obstacles",
       {obstacle("floor", {{"type", "half_plane"}, {"point", {0, 0}}, {"normal", {0, 1}}}),
        obstacle("peg", {{"type", "circle"}, {"center", {0, 1}}, {"radius", 0.5}})}}};
  Sim sim(scene, {{Vec2(2.0, 1.0), Vec2::Zero()}});
  pinsim_state_view sv{1, 0.0, sim.x.data(), sim.v.data(), sim.w.data(), sim.r.data()};
  const OutlineSet set = sim.backend->outline(StateView(sv), 1e-3);
  // the peg (-0.5..0.5, 0.5..1.5), the floor's point (0, 0) and the ball's centre (2, 1):
  // 2.5 wide, grown by 0.25; the floor is the part below y = 0
  const pinsim_bounds& fl = set.obstacles[0].bounds;
  CHECK(fl.x0 == Approx(-0.75));
  CHECK(fl.x1 == Approx(2.25));
  CHECK(fl.y0 == Approx(-0.25));
  CHECK(fl.y1 == 0.0);
  check_on_boundary(sim.backend->field(), 1, set.obstacles[1], 0.0, 1e-3);
}

TEST_CASE("outline: a subtraction keeps the first shape's boundary outside the others") {
  // a bowl: the box minus a circle above it (blob_obstacles.json)
  const json scene = {
      {"obstacles",
       {obstacle("bowl", {{"type", "subtraction"},
                          {"shapes",
                           {{{"type", "box"}, {"center", {0.0, 0.15}}, {"half_size", {0.7, 0.15}}},
                            {{"type", "circle"}, {"center", {0.0, 0.95}}, {"radius", 0.85}}}}})}}};
  Sim sim(scene, {});
  pinsim_state_view sv{0, 0.0, nullptr, nullptr, nullptr, nullptr};
  const OutlineSet set = sim.backend->outline(StateView(sv), 1e-4);
  check_on_boundary(sim.backend->field(), 0, set.obstacles[0], 0.0, 1e-4);
  CHECK(set.bounds.y1 == Approx(0.3));  // not the circle's top: it is not boundary
  CHECK(set.bounds.y0 == Approx(0.0));
}
