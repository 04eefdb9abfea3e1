// Physics of the sdf backend against closed forms.
#include <cmath>
#include <numbers>
#include <random>

#include "sdf_harness.hpp"

using namespace pinsim;
using namespace pinsim::sdf;
using namespace pinsim::sdf::test;
using nlohmann::json;

namespace {

json box_container(double hx, double hy, double e = 1.0) {
  return {{"obstacles",
           {obstacle("walls",
                     {{"type", "inside"},
                      {"shape", {{"type", "box"}, {"center", {0, 0}}, {"half_size", {hx, hy}}}}},
                     e)}}};
}

/// Closed-form triangle wave: a point bouncing elastically between a and b, starting at
/// x0 with velocity v (unfold the motion onto a line of period 2 (b - a)).
double triangle(double a, double b, double x0, double v, double t) {
  const double len = b - a;
  double s = std::fmod(x0 - a + v * t, 2.0 * len);
  if (s < 0.0) s += 2.0 * len;
  return a + (s <= len ? s : 2.0 * len - s);
}

/// One step of `a` (a backend that keeps its records between steps) and of a fresh backend
/// from the previous fresh state `b` (which cannot reuse anything): every particle's
/// position and velocity must agree to the bit. `b` becomes the fresh state.
void step_against_fresh(Sim& a, std::vector<Ball>& b, const json& scene, const json& par, double dt,
                        const Vec2& g) {
  Sim fresh(scene, b, par);
  fresh.t = a.t;
  fresh.step(dt, g);
  a.step(dt, g);
  for (std::size_t i = 0; i < b.size(); ++i) {
    b[i].x = fresh.pos(i);
    b[i].v = fresh.vel(i);
    REQUIRE(a.pos(i).x() == b[i].x.x());
    REQUIRE(a.pos(i).y() == b[i].x.y());
    REQUIRE(a.vel(i).x() == b[i].v.x());
    REQUIRE(a.vel(i).y() == b[i].v.y());
  }
}

}  // namespace

TEST_CASE("ball in an empty box with e = 1 follows the triangle wave, energy exact") {
  // The seed's 1D test problem, in both axes at once: no gravity, e = 1; the centre
  // bounces between -(h - r - depth_min) and +(h - r - depth_min) in x and in y.
  const double hx = 1.0, hy = 0.7, r = 0.05, dt = 1e-3;
  const Vec2 v0(123.4, -37.7);
  Sim sim(box_container(hx, hy), {{Vec2(0.1, -0.2), v0, r}});
  const double dm = sim.backend->depth_min();
  const double ax = hx - r - dm, ay = hy - r - dm;
  const int steps = 40000;
  double max_err = 0.0;
  for (int n = 1; n <= steps; ++n) {
    sim.step(dt);
    const double t = n * dt;
    const Vec2 exact(triangle(-ax, ax, 0.1, v0.x(), t), triangle(-ay, ay, -0.2, v0.y(), t));
    max_err = std::max(max_err, (sim.pos() - exact).norm());
    // e = 1 and axis-aligned normals: each reflection flips the sign of a component exactly
    REQUIRE(std::abs(sim.vel().x()) == std::abs(v0.x()));
    REQUIRE(std::abs(sim.vel().y()) == std::abs(v0.y()));
  }
  // hits: |v| T / (2a) per axis
  const double hits =
      std::abs(v0.x()) * steps * dt / (2 * ax) + std::abs(v0.y()) * steps * dt / (2 * ay);
  CHECK(hits > 3000);
  CHECK(std::abs(static_cast<double>(sim.events.size()) - hits) <= 2.0);
  CHECK(max_err < 1e-8);
  CHECK(sim.backend->stats().cap_hits == 0);
  const double ke0 = 0.5 * v0.squaredNorm(), ke1 = 0.5 * sim.vel().squaredNorm();
  CHECK(ke1 == ke0);
}

TEST_CASE("bouncing ball with e < 1: impact times and apex heights match the closed form") {
  // Drop from height h0 above the floor: first impact t1 = sqrt(2 h0 / g) at speed
  // v1 = sqrt(2 g h0); after k bounces the speed is e^k v1, the apex h_k = e^(2k) h0 and
  // the flight lasts 2 e^k v1 / g, so t_(k+1) = t_k + 2 e^k v1 / g.
  const double g = 9.81, h0 = 1.0, e = 0.8, r = 0.05, dt = 1e-4;
  json scene = {
      {"obstacles",
       {obstacle("floor", {{"type", "half_plane"}, {"point", {0, 0}}, {"normal", {0, 1}}}, e)}}};
  Sim sim(scene, {{Vec2(0, h0 + r), Vec2::Zero(), r}});
  const double base = r + sim.backend->depth_min();  // the centre's height at contact
  const double v1 = std::sqrt(2 * g * (h0 - sim.backend->depth_min()));
  std::vector<double> apex;
  double ymax = 0.0;
  std::size_t seen = 0;
  const int bounces = 8;
  while (sim.events.size() < static_cast<std::size_t>(bounces) && sim.t < 20.0) {
    sim.step(dt, Vec2(0, -g));
    ymax = std::max(ymax, sim.pos().y());
    if (sim.events.size() > seen) {
      seen = sim.events.size();
      apex.push_back(ymax - base);
      ymax = 0.0;
    }
  }
  REQUIRE(sim.events.size() == static_cast<std::size_t>(bounces));
  double t_exact = v1 / g;
  for (int k = 0; k < bounces; ++k) {
    // symplectic Euler's position error is O(g t dt); allow a few steps per flight
    CHECK(sim.events[k].t == Approx(t_exact).margin(3 * dt * (k + 1)));
    CHECK(sim.events[k].vn_after == Approx(-e * sim.events[k].vn_before).epsilon(1e-12));
    t_exact += 2 * std::pow(e, k + 1) * v1 / g;
  }
  for (int k = 1; k < bounces; ++k)  // apex before impact k+1 follows bounce k
    CHECK(apex[k] == Approx(std::pow(e, 2 * k) * (h0 - sim.backend->depth_min())).epsilon(2e-3));
}

TEST_CASE("a wall moving at u hits a ball at rest: the ball leaves at 2u, one impulse") {
  // Elastic collision with an infinitely heavy wall: in the wall's frame the ball arrives
  // at -u and leaves at +u, so in the lab frame v' = 2u (e = 1).
  const double u = 2.0, r = 0.05, dt = 5e-4;
  json scene = {
      {"obstacles",
       {{{"id", "piston"},
         {"shape", {{"type", "box"}, {"center", {-0.45, 0}}, {"half_size", {0.05, 0.5}}}},
         {"material", {{"restitution", 1.0}}},
         {"motion", {{"type", "slider"}, {"offset", {1.0, 0}}, {"speed", u}, {"input", "go"}}}}}},
      {"inputs", {{{"t", 0.0}, {"input", "go"}, {"action", "press"}}}}};
  Sim sim(scene, {{Vec2(0.3, 0), Vec2::Zero(), r}});
  for (int n = 0; n < 2000; ++n) sim.step(dt);
  REQUIRE(sim.events.size() == 1);
  CHECK(sim.vel().x() == Approx(2 * u).epsilon(1e-12));
  CHECK(sim.vel().y() == 0.0);
  // gap 0.3 - r - (-0.4) = 0.65, closed at speed u, contact depth_min early
  const double t_hit = (0.65 - sim.backend->depth_min()) / u;
  CHECK(sim.events[0].t == Approx(t_hit).margin(1e-9));
  CHECK(sim.events[0].vn_before == Approx(-u));
  CHECK(sim.events[0].vn_after == Approx(u));
  CHECK(sim.pos().x() == Approx(0.3 + 2 * u * (sim.t - t_hit)).epsilon(1e-9));
}

TEST_CASE("balls fired at walls far thinner than their travel per step never cross") {
  // thickness 1e-4; travel per step up to 1e4 * thickness = 1 length unit.
  const double thick = 1e-4, dt = 1e-3, r = 0.01;
  const json walls[] = {
      {{"type", "box"}, {"center", {0, 0}}, {"half_size", {0.5 * thick, 50}}},
      {{"type", "capsule"}, {"a", {0, -50}}, {"b", {0, 50}}, {"radius", 0.0}},  // zero thickness
      {{"type", "polygon"}, {"points", {{0, -50}, {thick, 0}, {0, 50}}}},       // sliver
  };
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int shots = 0, crossed = 0;
  for (const json& wall : walls) {
    for (int k = 0; k < 1500; ++k) {
      const double e = U(rng);
      Sim sim({{"obstacles", {obstacle("wall", wall, e)}}},
              {{Vec2(-0.1 - 3 * U(rng), 10 * (U(rng) - 0.5)), Vec2::Zero(), r}});
      const double ang = (U(rng) - 0.5) * 0.98 * std::numbers::pi;  // towards +x
      const double speed = (1e4 * thick / dt) * (0.05 + 0.95 * U(rng));
      sim.v[0] = speed * std::cos(ang);
      sim.v[1] = speed * std::sin(ang);
      for (int n = 0; n < 8; ++n) {
        sim.step(dt);
        if (sim.pos().x() > 0.0) break;
      }
      ++shots;
      if (sim.pos().x() > 0.0) ++crossed;
    }
  }
  // a thin wedge: fired into the corner of a V made of two zero-thickness segments
  for (int k = 0; k < 1500; ++k) {
    json vee = {
        obstacle("upper", {{"type", "capsule"}, {"a", {0, 0}}, {"b", {-20, 20}}, {"radius", 0.0}}),
        obstacle("lower",
                 {{"type", "capsule"}, {"a", {0, 0}}, {"b", {-20, -20}}, {"radius", 0.0}})};
    const double x0 = -1.0 - 5.0 * U(rng);
    const double y0 = (U(rng) - 0.5) * (-x0 - 0.1);
    Sim sim({{"obstacles", vee}}, {{Vec2(x0, y0), Vec2::Zero(), r}});
    const Vec2 aim = (Vec2(-0.05 * U(rng), 0.1 * (U(rng) - 0.5)) - Vec2(x0, y0)).normalized();
    const double speed = (1e4 * thick / dt) * (0.05 + 0.95 * U(rng));
    sim.v[0] = speed * aim.x();
    sim.v[1] = speed * aim.y();
    bool out = false;
    for (int n = 0; n < 8; ++n) {
      sim.step(dt);
      out = out || sim.pos().x() + std::abs(sim.pos().y()) > 0.0;  // beyond either wall's line
    }
    ++shots;
    if (out) ++crossed;
  }
  CHECK(shots == 6000);
  CHECK(crossed == 0);
}

TEST_CASE("a flipper hit sends a resting ball off with twice its normal speed (e = 1)") {
  // A capsule flipper along +x rotating at omega hits a ball at rest. At impact the contact
  // point moves with u = omega x (p - pivot); its normal component is omega * xi, xi the
  // ball centre's coordinate along the flipper. With e = 1 the ball leaves at 2 omega xi n.
  const double w = 20.0, rf = 0.01, r = 0.02, dt = 1e-4;
  json scene = {{"obstacles",
                 {{{"id", "flipper"},
                   {"shape", {{"type", "capsule"}, {"a", {0, 0}}, {"b", {0.3, 0}}, {"radius", rf}}},
                   {"material", {{"restitution", 1.0}}},
                   {"motion",
                    {{"type", "flipper"},
                     {"pivot", {0, 0}},
                     {"rest_angle", 0.0},
                     {"raised_angle", 0.8},
                     {"angular_speed", w},
                     {"input", "left"}}}}}},
                {"inputs", {{{"t", 0.0}, {"input", "left"}, {"action", "press"}}}}};
  const Vec2 p0(0.2, 0.08);
  Sim sim(scene, {{p0, Vec2::Zero(), r}});
  for (int n = 0; n < 400; ++n) sim.step(dt);
  REQUIRE(sim.events.size() == 1);
  const pinsim_event& ev = sim.events[0];
  const Vec2 n(ev.normal[0], ev.normal[1]);
  // the flipper angle at impact: p0's distance from the flipper's axis is rf + r + depth_min
  // (up to the march tolerance)
  const double hgt = rf + r + sim.backend->depth_min();
  const double phi_exact = std::atan2(p0.y(), p0.x()) - std::asin(hgt / p0.norm());
  const double phi = std::atan2(-n.x(), n.y());  // normal (-sin phi, cos phi)
  CHECK(phi == Approx(phi_exact).margin(1e-5));
  CHECK(ev.t == Approx(phi / w).margin(1e-6));
  const double xi = p0.dot(Vec2(std::cos(phi), std::sin(phi)));
  CHECK(ev.vn_before == Approx(-w * xi).epsilon(1e-6));
  CHECK(sim.vel().x() == Approx(2 * w * xi * n.x()).epsilon(1e-6));
  CHECK(sim.vel().y() == Approx(2 * w * xi * n.y()).epsilon(1e-6));
}

TEST_CASE("a flipper pushing a resting ball (e = 0) releases it with the bead-on-a-rod speed") {
  // Frictionless ball pushed by a flipper rotating at constant omega, on a line parallel
  // to the flipper's axis at height h: in the rotating frame xi'' = omega^2 xi (centrifugal),
  // with xi(0) = xi0 and xi'(0) = omega h (the ball starts at rest in the lab frame). So
  // xi(t) = xi0 cosh(wt) + h sinh(wt). When the flipper stops at T = dtheta / omega the ball
  // leaves with, in flipper axes, (xi'(T) - omega h, omega xi(T)).
  const double w = 10.0, dth = 0.3, rf = 0.01, r = 0.02, dt = 2e-6, xi0 = 0.1;
  json scene = {{"obstacles",
                 {{{"id", "flipper"},
                   {"shape", {{"type", "capsule"}, {"a", {0, 0}}, {"b", {0.3, 0}}, {"radius", rf}}},
                   {"material", {{"restitution", 0.0}}},
                   {"motion",
                    {{"type", "flipper"},
                     {"pivot", {0, 0}},
                     {"rest_angle", 0.0},
                     {"raised_angle", dth},
                     {"angular_speed", w},
                     {"input", "left"}}}}}},
                {"inputs", {{{"t", 0.0}, {"input", "left"}, {"action", "press"}}}}};
  Sim probe(scene, {});
  const double h = rf + r + probe.backend->depth_min();
  Sim sim(scene, {{Vec2(xi0, h), Vec2::Zero(), r}});
  const double T = dth / w;
  while (sim.t < T + 0.005) sim.step(dt);
  const double wt = w * T;
  const double xi = xi0 * std::cosh(wt) + h * std::sinh(wt);
  const double dxi = w * xi0 * std::sinh(wt) + w * h * std::cosh(wt);
  const Vec2 local(dxi - w * h, w * xi);
  const Vec2 exact = Eigen::Rotation2Dd(dth) * local;
  CHECK((sim.vel() - exact).norm() < 1e-4 * exact.norm());
  CHECK(sim.backend->stats().cap_hits == 0);
  // the ball's speed is the speed the flipper's surface had under it when it let go
  CHECK(local.y() == Approx(w * xi));
}

TEST_CASE("a fast thin flipper never passes through a ball") {
  // The march bound includes the flipper's own speed omega * reach: a 0.2 mm thick flipper
  // whose tip moves 0.5 per step sweeps over balls at rest and must push every one ahead.
  const double w = 500.0, len = 1.0, dt = 1e-3, r = 0.01;
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int behind = 0;
  for (int k = 0; k < 500; ++k) {
    json scene = {
        {"obstacles",
         {{{"id", "flipper"},
           {"shape", {{"type", "capsule"}, {"a", {0, 0}}, {"b", {len, 0}}, {"radius", 1e-4}}},
           {"material", {{"restitution", U(rng)}}},
           {"motion",
            {{"type", "flipper"},
             {"pivot", {0, 0}},
             {"rest_angle", 0.0},
             {"raised_angle", 1.2},
             {"angular_speed", w},
             {"input", "x"}}}}}},
        {"inputs", {{{"t", 0.0}, {"input", "x"}, {"action", "press"}}}}};
    const double rho = 0.1 + 0.8 * U(rng), ang = 0.05 + 1.0 * U(rng);
    Sim sim(scene, {{rho * Vec2(std::cos(ang), std::sin(ang)), Vec2::Zero(), r}});
    for (int n = 0; n < 4; ++n) sim.step(dt);  // 2.4 ms > 1.2 / 500
    const double a = std::atan2(sim.pos().y(), sim.pos().x());
    if (sim.pos().norm() < len && a < 1.2) ++behind;
    if (sim.pos().norm() >= len && sim.events.empty()) ++behind;
  }
  CHECK(behind == 0);
}

TEST_CASE("a resting ball on a floor stays within the contact offset for 1e5 steps") {
  const double g = 9.81, r = 0.0135, dt = 1e-4;
  json scene = {
      {"obstacles",
       {obstacle("floor", {{"type", "half_plane"}, {"point", {0, 0}}, {"normal", {0, 1}}}, 0.5)}}};
  // rest_speed above g dt: slow impacts are resting contacts (no bounce, no event)
  Sim sim(scene, {{Vec2(0, r), Vec2::Zero(), r}}, {{"rest_speed", 0.01}});
  const double dm = sim.backend->depth_min(), tol = sim.backend->march_tolerance();
  double lo = HUGE_VAL, hi = -HUGE_VAL;
  for (int n = 0; n < 100000; ++n) {
    sim.step(dt, Vec2(0, -g));
    const double gap = sim.pos().y() - r;
    lo = std::min(lo, gap);
    hi = std::max(hi, gap);
    if (n > 0) REQUIRE(sim.vel().y() == 0.0);  // no chatter
  }
  CHECK(lo >= 0.0);
  CHECK(hi <= dm + tol);
  CHECK(hi - lo <= dm + tol);
  CHECK(sim.events.empty());
  CHECK(sim.backend->stats().cap_hits == 0);
}

TEST_CASE("a ball sliding round the inside of a circular wall keeps its speed, on the circle") {
  // Frictionless, e = 1, no gravity: a ball launched tangentially inside a circle of radius
  // R runs round it at constant speed V on the circle of radius rho = R - r (less the
  // contact offset), so after time T it has turned by V T / rho. Impulses reflect the
  // normal velocity, so |v| is kept to rounding; the ball never goes past the surface.
  const double R = 0.25, r = 0.0135, V = 2.0, dt = 2e-4;
  json scene = {
      {"obstacles",
       {obstacle("wall", {{"type", "inside"},
                          {"shape", {{"type", "circle"}, {"center", {0, 0}}, {"radius", R}}}})}}};
  Sim sim(scene, {{Vec2(R - r - 1e-5, 0), Vec2(0, V), r}});
  const double dm = sim.backend->depth_min();
  const int steps = 5000;
  double lo = HUGE_VAL, hi = -HUGE_VAL;
  for (int n = 0; n < steps; ++n) {
    sim.step(dt);
    const double gap = R - sim.pos().norm() - r;
    lo = std::min(lo, gap);
    hi = std::max(hi, gap);
  }
  CHECK(lo >= 0.0);
  CHECK(hi <= 2 * dm);
  CHECK(sim.vel().norm() == Approx(V).epsilon(1e-9));
  const double rho = R - r - dm;
  const double turned = std::atan2(sim.pos().y(), sim.pos().x());
  const double exact = std::remainder(V * steps * dt / rho, 2 * M_PI);
  CHECK(std::remainder(turned - exact, 2 * M_PI) == Approx(0.0).margin(1e-3));
  CHECK(sim.backend->stats().cap_hits == 0);
  // sliding takes the step whole instead of depth_min at a time (V dt / depth_min = 40)
  CHECK(sim.backend->stats().queries <= 4u * steps);
}

TEST_CASE("a ball sliding along a box floor into a corner stays out of the walls") {
  // Under gravity on the floor of a container box, thrown along it at 3 m/s with e = 0.5:
  // it slides to the side wall, bounces off at 1.5 m/s (its normal speed times e), and
  // never ends a step past any surface.
  const double r = 0.01, dt = 2e-4, g = 9.81;
  json scene = {
      {"obstacles",
       {obstacle("box",
                 {{"type", "inside"},
                  {"shape", {{"type", "box"}, {"center", {0, 0}}, {"half_size", {0.2, 0.1}}}}},
                 0.5)}}};
  Sim sim(scene, {{Vec2(0, -0.1 + r + 1e-5), Vec2(3.0, 0), r}}, {{"rest_speed", 0.01}});
  for (int n = 0; n < 1000; ++n) {
    sim.step(dt, Vec2(0, -g));
    const Vec2 p = sim.pos();
    REQUIRE(p.y() + 0.1 - r >= 0.0);
    REQUIRE(0.2 - p.x() - r >= 0.0);
    REQUIRE(p.x() + 0.2 - r >= 0.0);
  }
  REQUIRE(sim.events.size() == 1);
  CHECK(sim.events[0].vn_before == Approx(-3.0).epsilon(1e-12));
  CHECK(sim.vel().x() == Approx(-1.5).epsilon(1e-12));
}

TEST_CASE("particle-particle contacts only when the scene turns them on") {
  // Equal masses, head-on, e = 1: the velocities are exchanged.
  const std::vector<Ball> balls = {{Vec2(-0.5, 0), Vec2(1, 0), 0.1},
                                   {Vec2(0.5, 0), Vec2(-1, 0), 0.1}};
  Sim off({{"obstacles", json::array()}}, balls);
  Sim on({{"obstacles", json::array()}, {"contacts", {{"particles", true}, {"restitution", 1.0}}}},
         balls);
  for (int n = 0; n < 1000; ++n) {
    off.step(1e-3);
    on.step(1e-3);
  }
  CHECK(off.events.empty());
  CHECK(off.pos(0).x() == Approx(0.5));
  REQUIRE(on.events.size() == 1);
  CHECK(on.events[0].t == Approx(0.4));  // gap 0.8 closed at relative speed 2
  CHECK(on.vel(0).x() == Approx(-1.0));
  CHECK(on.vel(1).x() == Approx(1.0));
  CHECK(on.pos(0).x() == Approx(-0.1 - 0.6));  // contact at t=0.4, then 0.6 s back at speed 1
  CHECK(on.pos(1).x() == Approx(0.1 + 0.6));
}

TEST_CASE("bumper kick and Coulomb friction change the velocity by the closed form") {
  // One impact on a floor: normal v_n' = -e v_n + kick; tangential speed reduced by
  // min(mu (1 + e) |v_n|, |v_t|) (Coulomb limit on the tangential impulse, point ball).
  const double e = 0.5, mu = 0.2, kick = 0.3, dt = 1e-3;
  json scene = {{"obstacles",
                 {obstacle("floor", {{"type", "half_plane"}, {"point", {0, 0}}, {"normal", {0, 1}}},
                           e, mu, kick)}}};
  const Vec2 v0(2.0, -1.5);
  Sim sim(scene, {{Vec2(0, 0.1), v0, 0.05}});
  for (int n = 0; n < 60; ++n) sim.step(dt);
  REQUIRE(sim.events.size() == 1);
  CHECK(sim.vel().y() == Approx(e * 1.5 + kick));
  CHECK(sim.vel().x() == Approx(2.0 - mu * (1 + e) * 1.5));
  CHECK(sim.events[0].vn_before == Approx(-1.5));
  CHECK(sim.events[0].vn_after == Approx(e * 1.5 + kick));
  CHECK(sim.events[0].point[1] == Approx(0.0).margin(1e-12));
}

TEST_CASE("reused resting steps equal fresh ones, and a slider that can reach stops them") {
  // Two balls at rest on a floor; at t = 0.1 s a slider starts towards the first and pushes
  // it away; the second is out of its reach. One backend (which reuses resting steps)
  // against a fresh backend every step (which cannot): they must agree to the bit.
  const double g = 9.81, r = 0.01, dt = 1e-3;
  const json scene = {
      {"obstacles",
       {obstacle("floor", {{"type", "box"}, {"center", {0, -0.05}}, {"half_size", {1, 0.05}}}, 0.5),
        {{"id", "pusher"},
         {"shape", {{"type", "box"}, {"center", {-0.3, 0.02}}, {"half_size", {0.02, 0.02}}}},
         {"material", {{"restitution", 0.5}}},
         {"motion",
          {{"type", "slider"}, {"offset", {0.4, 0}}, {"speed", 1.0}, {"input", "push"}}}}}},
      {"inputs", {{{"t", 0.1}, {"input", "push"}, {"action", "press"}}}}};
  const json par = {{"rest_speed", 0.02}};
  const std::vector<Ball> start = {{Vec2(0, r), Vec2::Zero(), r}, {Vec2(0.8, r), Vec2::Zero(), r}};
  Sim a(scene, start, par);
  std::vector<Ball> b = start;
  for (int n = 0; n < 600; ++n) step_against_fresh(a, b, scene, par, dt, Vec2(0, -g));
  // the second ball's steps are reuses once its resting position has cycled through its
  // few rounding values; the first ball's never are (the slider can reach it)
  CHECK(a.backend->stats().reuses >= 590);
  CHECK(a.pos(0).x() > 0.05);  // pushed
  CHECK(a.pos(1).x() == 0.8);
}

TEST_CASE("resting on a moving obstacle that stands still is reused, and stops when it moves") {
  // A ball lifted by a platform (slider) and a ball dropped on a raised flipper, both
  // e = 0: once the platform has stopped and the flipper is up they rest on moving
  // obstacles that stand still, and their steps are reused (a still epoch); at t = 0.6 s
  // both are released and the balls must follow them down. Against a fresh backend every
  // step (which cannot reuse): equal to the bit.
  const double g = 9.81, r = 0.01, dt = 1e-3;
  const json still = {{"restitution", 0.0}};
  const json scene = {
      {"obstacles",
       {{{"id", "platform"},
         {"shape", {{"type", "box"}, {"center", {0, 0}}, {"half_size", {0.1, 0.01}}}},
         {"material", still},
         {"motion", {{"type", "slider"}, {"offset", {0, 0.1}}, {"speed", 0.5}, {"input", "lift"}}}},
        {{"id", "flipper"},
         {"shape", {{"type", "capsule"}, {"a", {0, 0}}, {"b", {0.15, 0}}, {"radius", 0.01}}},
         {"material", still},
         {"motion",
          {{"type", "flipper"},
           {"pivot", {0.5, 0}},
           {"rest_angle", -0.5},
           {"raised_angle", 0.0},
           {"angular_speed", 20.0},
           {"input", "flip"}}}}}},
      {"inputs",
       {{{"t", 0.0}, {"input", "lift"}, {"action", "press"}},
        {{"t", 0.0}, {"input", "flip"}, {"action", "press"}},
        {{"t", 0.6}, {"input", "lift"}, {"action", "release"}},
        {{"t", 0.6}, {"input", "flip"}, {"action", "release"}}}}};
  const json par = {{"rest_speed", 0.05}};
  const std::vector<Ball> start = {{Vec2(0, 0.01 + r + 1e-4), Vec2::Zero(), r},
                                   {Vec2(0.6, 0.05), Vec2::Zero(), r}};
  Sim a(scene, start, par);
  std::vector<Ball> b = start;
  uint64_t reuses_at_release = 0;
  Vec2 rest0, rest1;
  for (int n = 0; n < 800; ++n) {
    step_against_fresh(a, b, scene, par, dt, Vec2(0, -g));
    if (n == 599) {
      reuses_at_release = a.backend->stats().reuses;
      rest0 = a.pos(0);
      rest1 = a.pos(1);
    }
  }
  // both rest from well before 0.4 s: at least 2 x 200 reused steps before the release
  INFO("reuses before the release " << reuses_at_release);
  CHECK(reuses_at_release >= 400);
  // resting on top of the raised platform (y = 0.1 + 0.01 + r) and on the flat flipper
  CHECK(rest0.y() == Approx(0.12).margin(1e-4));
  CHECK(rest1.y() == Approx(0.02).margin(1e-4));
  // released: both went down with their obstacles
  CHECK(a.pos(0).y() < rest0.y() - 0.02);
  CHECK(a.pos(1).y() < rest1.y() - 0.02);
}
