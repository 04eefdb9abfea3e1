// XPBD (integrator_xpbd.cpp) against closed forms: a hard constraint satisfied by one
// projection, the compliant update against the spring force as h -> 0, one step of a damped
// oscillator against implicit Euler (which XPBD with one sweep is, for a linear spring), the
// energy factor of the undamped oscillator over 10 s, the two-mass period; forces without
// constraints as external forces; the scene's "xpbd" settings and their errors.
#include <catch2/catch.hpp>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "test_support.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;
using nlohmann::json;

namespace {

Scene make_scene(const json& doc, const std::vector<std::string>& set = {}) {
  return parse_scene(doc.dump(), "xpbd.json", PINSIM_TEST_FIXTURE_DIR, set);
}

/// Two free particles (masses m0, m1) on one damped_spring of rest length L, no gravity.
json pair_scene(double ks, double kd, double L, const std::vector<double>& x1,
                const std::vector<double>& v1, double h, uint32_t substeps = 1,
                uint32_t iterations = 1, double m0 = 1.0, double m1 = 3.0) {
  return {{"time", {{"dt", h}, {"duration", 1.0}}},
          {"integrator", "xpbd"},
          {"xpbd", {{"substeps", substeps}, {"iterations", iterations}}},
          {"particles",
           {{{"x", {0.0, 0.0}}, {"v", {0.0, 0.0}}, {"mass", m0}},
            {{"x", x1}, {"v", v1}, {"mass", m1}}}},
          {"forces",
           {{{"type", "damped_spring"},
             {"params", {{"ks", ks}, {"kd", kd}, {"rest_length", L}}},
             {"elements", {{0, 1}}}}}},
          {"checks", {{"energy_blowup", 1e300}, {"energy_every", 1000000000}}}};
}

/// A particle of mass m on a zero-rest-length spring k = m w^2 to a pinned one at the origin.
json oscillator(const std::string& integrator, double w, double h, double T, double kd = 0.0,
                uint32_t substeps = 1, double m = 2.0) {
  return {{"time", {{"dt", h}, {"duration", T}}},
          {"integrator", integrator},
          {"xpbd", {{"substeps", substeps}, {"iterations", 1}}},
          {"particles", {{{"x", {0.0, 0.0}}, {"pinned", true}}, {{"x", {1.0, 0.0}}, {"mass", m}}}},
          {"forces",
           {{{"type", "damped_spring"},
             {"params", {{"ks", m * w * w}, {"kd", kd}, {"rest_length", 0.0}}},
             {"elements", {{0, 1}}}}}},
          {"checks", {{"energy_blowup", 1e300}, {"energy_every", 1000000000}}}};
}

double energy(const Simulation& s) {
  return s.kinetic_energy(s.state()) + s.potential_energy(s.state());
}

}  // namespace

TEST_CASE("xpbd: with alpha = 0 one projection satisfies a distance constraint exactly") {
  // ks = 1e100 (the largest parameter value): alpha~ = 1/(ks h^2) = 1e-96, zero beside w0 + w1. One
  // projection of C = |p1 - p0| - L along its gradient moves the separation by -(w0 + w1) C / (w0 +
  // w1) = -C (Macklin et al. 2016, eq. 18 with alpha~ = 0), so after one step |x1 - x0| = L to
  // rounding, whatever the velocities made of the prediction. Momentum is kept: m0 dx0 + m1 dx1 =
  // 0.
  const double L = 1.0;
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(make_scene(pair_scene(1e100, 0.0, L, {1.3, 0.4}, {2.0, -1.0}, 0.01)), loader);
  const Eigen::Vector2d p0 = sim.state().x.col(0) + 3.0 * sim.state().x.col(1);
  sim.step();
  const State& s = sim.state();
  const double r = (s.x.col(1) - s.x.col(0)).norm();
  CHECK(std::abs(r - L) < 4e-15);
  // the centre of mass moves with the initial momentum (2, -1) * 3 / 4 over 0.01 s
  const Eigen::Vector2d p1 = s.x.col(0) + 3.0 * s.x.col(1);
  CHECK((p1 - p0 - 0.01 * 3.0 * Eigen::Vector2d(2.0, -1.0)).norm() < 1e-14);
  // a compliant spring (ks = 100) is not satisfied by one projection: the test can fail
  Simulation soft(make_scene(pair_scene(100.0, 0.0, L, {1.3, 0.4}, {2.0, -1.0}, 0.01)), loader);
  soft.step();
  CHECK(std::abs((soft.state().x.col(1) - soft.state().x.col(0)).norm() - L) > 1e-3);
}

TEST_CASE("xpbd: as h -> 0 the compliant update follows the spring's force") {
  // From rest with the spring stretched by C, one substep and one sweep: the prediction is
  // x itself, dlambda = -C / (W + 1/(ks h^2)) with W = w0 + w1 (|dC/dp_i| = 1), and
  //   v_i = w_i dC/dp_i dlambda / h = (h w_i f_i^spring) / (1 + ks h^2 W),
  // i.e. the symplectic Euler velocity h M^-1 f divided by 1 + ks h^2 W: the same to O(h^2).
  const double ks = 50.0, W = 1.0 + 1.0 / 3.0;
  PluginLoader loader(plugin_search_dirs());
  double last = 1.0;
  for (double h : {1e-2, 1e-3, 1e-4}) {
    CAPTURE(h);
    Simulation x(make_scene(pair_scene(ks, 0.0, 1.0, {1.1, 0.0}, {0.0, 0.0}, h)), loader);
    Simulation e(make_scene(pair_scene(ks, 0.0, 1.0, {1.1, 0.0}, {0.0, 0.0}, h),
                            {"integrator=symplectic_euler"}),
                 loader);
    x.step();
    e.step();
    const double factor = 1.0 + ks * h * h * W;
    // xpbd's velocity is a difference of positions over h: rounding of order eps |x| / h
    const double rounding = 4.0 * 2.3e-16 * 1.1 / h;
    for (int i = 0; i < 2; ++i) {
      const Eigen::Vector2d ve = e.state().v.col(i), vx = x.state().v.col(i);
      CHECK((vx * factor - ve).norm() <= 1e-12 * ve.norm() + factor * rounding);
    }
    const double rel = (x.state().v.col(1) - e.state().v.col(1)).norm() / e.state().v.col(1).norm();
    CHECK(rel < last / 50.0);  // O(h^2): 100x smaller per decade
    CHECK(rel < 2.0 * ks * h * h * W);
    last = rel;
  }
}

TEST_CASE("xpbd: one sweep on a damped linear spring is implicit Euler, damping beta = kd") {
  // 1D, particle on a zero-rest-length spring (C = |x|) with damping kd along it:
  // x'' = -w^2 x - c x', w^2 = k/m, c = kd/m. With alpha~ = 1/(k h^2) and
  // gamma = alpha~ kd h (eq. 26, beta = kd), the projection from p = x + h v gives
  //   x' = (x (1 + c h) + h v) / (1 + c h + w^2 h^2),
  // the backward Euler step of the damped oscillator (x' = x + h v', v' = v + h a(x', v')).
  const double w = 3.0, m = 2.0, kd = 0.8, c = kd / m, h = 0.05;
  json doc = oscillator("xpbd", w, h, 1.0, kd, 1, m);
  doc["particles"][1]["v"] = {0.7, 0.0};
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(make_scene(doc), loader);
  double x = 1.0, v = 0.7;
  for (int n = 0; n < 40; ++n) {
    sim.step();
    const double xn = (x * (1.0 + c * h) + h * v) / (1.0 + c * h + w * w * h * h);
    v = (xn - x) / h;
    x = xn;
    REQUIRE(std::abs(sim.state().x(0, 1) - x) < 1e-13);
    REQUIRE(std::abs(sim.state().v(0, 1) - v) < 1e-12);
    REQUIRE(sim.state().x(1, 1) == 0.0);
  }
}

TEST_CASE("xpbd: energy of an undamped oscillator over 10 s, substeps against one step") {
  // One sweep per substep on the linear oscillator is backward Euler (above, kd = 0): in the
  // coordinates (w x, v) each substep is a rotation scaled by 1/sqrt(1 + (w hs)^2), so
  // E_N / E_0 = (1 + (w hs)^2)^-N exactly, hs = dt / substeps, N = 10 s / hs. Small steps
  // (Macklin et al. 2019): 10 substeps of one sweep damp (1 + y^2/100)^-10 ~ 1 - y^2/10 per
  // step, one step of dt damps 1/(1 + y^2): less artificial damping at the same count of
  // constraint projections as one implicit Euler step's iteration.
  const double w = 3.0, dt = 0.02, T = 10.0;
  PluginLoader loader(plugin_search_dirs());
  double left[2];
  int k = 0;
  for (uint32_t sub : {1u, 10u}) {
    CAPTURE(sub);
    Simulation sim(make_scene(oscillator("xpbd", w, dt, T, 0.0, sub)), loader);
    const double e0 = energy(sim);
    for (uint64_t i = 0; i < sim.scene().steps(); ++i) sim.step();
    const double hs = dt / sub, n = T / hs;
    const double expect = std::pow(1.0 + w * w * hs * hs, -n);
    CHECK(std::abs(energy(sim) / e0 - expect) < 1e-9 + 1e-9 * expect);
    left[k++] = energy(sim) / e0;
  }
  CHECK(left[0] < 0.2);  // one step of dt: (1 + 0.0036)^-500 = 0.166
  CHECK(left[1] > 0.8);  // ten substeps: (1 + 3.6e-5)^-5000 = 0.835
}

TEST_CASE("xpbd: the two-mass oscillator's period is 2 pi sqrt(mu/k)") {
  // configs/two_mass_oscillator.json: m1 = 1, m2 = 3, k = 50, mu = 0.75: T = 0.769530 s.
  // Zero crossings of R - L (linear interpolation) half a period apart.
  const Scene s =
      load_scene(PINSIM_SOURCE_DIR "/configs/two_mass_oscillator.json",
                 {"integrator=xpbd", "xpbd.substeps=2", "time.dt=0.0005", "time.duration=4"});
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(s, loader);
  auto stretch = [&] { return (sim.state().x.col(1) - sim.state().x.col(0)).norm() - 1.0; };
  std::vector<double> crossings;
  double prev = stretch(), t_prev = 0.0;
  for (uint64_t i = 0; i < s.steps(); ++i) {
    sim.step();
    const double now = stretch(), t = sim.state().t;
    if ((prev > 0.0) != (now > 0.0))
      crossings.push_back(t_prev + (t - t_prev) * prev / (prev - now));
    prev = now;
    t_prev = t;
  }
  REQUIRE(crossings.size() >= 8);
  const double period =
      2.0 * (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
  const double expect = 2.0 * M_PI * std::sqrt(0.75 / 50.0);
  CHECK(std::abs(period - expect) < 1e-4 * expect);
  // the centre of mass stays at rest, to the rounding of velocities made of position
  // differences (eps |x| / h per substep, a random walk over 16000 substeps)
  const Eigen::Vector2d com = sim.state().x.col(0) + 3.0 * sim.state().x.col(1);
  CHECK(std::abs(com.x() - 3.3) < 1e-8);
}

TEST_CASE(
    "xpbd: a force without constraints is an external force: free flight as symplectic "
    "Euler") {
  // No constraint: v += h a, p = x + h v, and the correction (p - p) / h is exactly zero, so the
  // step is symplectic Euler's, to the bit.
  PluginLoader loader(plugin_search_dirs());
  const std::string scene = PINSIM_SOURCE_DIR "/configs/projectile.json";
  Simulation a(load_scene(scene, {"integrator=xpbd"}), loader);
  Simulation b(load_scene(scene, {"integrator=symplectic_euler"}), loader);
  for (int i = 0; i < 500; ++i) {
    a.step();
    b.step();
  }
  CHECK(a.state().hash() == b.state().hash());
  const json stats = a.integrator_stats();
  REQUIRE(stats["external_forces"].size() == 1);
  CHECK(stats["constraints"] == 0);
}

TEST_CASE("xpbd: a pure damper (ks = 0, kd > 0) is backward Euler on the velocities") {
  // A two-mass dashpot along x: m0 = 1 at x = 0 moving at +1, m1 = 3 at x = 1 moving at -1,
  // one damped_spring with ks = 0 and kd = 2 (f_0 = -kd J_0 (J v), J = dR/dp, R = |p0 - p1|).
  // The closing speed u = J v = dR/dt obeys du/dt = -kd W u, W = 1/m0 + 1/m1 = 4/3 (it is the
  // relative velocity along the line, and the damper acts only along it), so continuously
  // u(t) = u0 exp(-kd W t), u0 = -2. The damper's backward Euler step of h multiplies u by
  // exactly 1 / (1 + h kd W) (the velocity update in xpbd_constraints.cpp), and momentum
  // m0 v0 + m1 v1 = -2 stays. Over 0.3 s the bodies close by 2 (1 - e^-0.8) / (8/3) = 0.41 < 1.
  const double kd = 2.0, W = 4.0 / 3.0, T = 0.3, u0 = -2.0;
  PluginLoader loader(plugin_search_dirs());
  auto run = [&](double h, uint32_t substeps) {
    json doc = pair_scene(0.0, kd, 1.0, {1.0, 0.0}, {-1.0, 0.0}, h, substeps, 1, 1.0, 3.0);
    doc["particles"][0]["v"] = {1.0, 0.0};
    doc["time"]["duration"] = T;
    Simulation sim(make_scene(doc), loader);
    for (uint64_t i = 0; i < sim.scene().steps(); ++i) sim.step();
    const json stats = sim.integrator_stats();
    CHECK(stats["dampers"] == 1);
    CHECK(stats["constraints"] == 0);
    const State& s = sim.state();
    CHECK(std::abs(s.v(0, 0) + 3.0 * s.v(0, 1) + 2.0) < 1e-14);  // momentum
    CHECK(s.v(1, 0) == 0.0);
    CHECK(s.v(1, 1) == 0.0);
    return s.v(0, 1) - s.v(0, 0);  // u = dR/dt = v1 - v0 along x (p1 is right of p0)
  };
  // the discrete closed form, 30 steps of 2 substeps
  const double h = 0.01;
  const double discrete = u0 * std::pow(1.0 + 0.5 * h * kd * W, -60.0);
  CHECK(std::abs(run(h, 2) - discrete) < 1e-13);
  // the continuous limit: first order in h (backward Euler's error ~ (kd W)^2 h T / 2 |u|)
  const double exact = u0 * std::exp(-kd * W * T);
  const double e3 = std::abs(run(1e-3, 1) - exact), e4 = std::abs(run(1e-4, 1) - exact);
  CHECK(e4 < 2e-4 * std::abs(exact));
  CHECK(e3 / e4 > 8.0);
  CHECK(e3 / e4 < 12.0);
}

TEST_CASE("xpbd: a stiff pure damper at a large step stays stable and damps monotonically") {
  // kd = 1e6 at h = 1/60: h kd W = 2.2e4, far beyond an explicit damper's limit h kd W < 2;
  // backward Euler multiplies the closing speed by 1 / (1 + 2.2e4) per step.
  PluginLoader loader(plugin_search_dirs());
  json doc = pair_scene(0.0, 1e6, 1.0, {1.0, 0.0}, {-1.0, 0.0}, 1.0 / 60.0, 1, 1, 1.0, 3.0);
  doc["particles"][0]["v"] = {1.0, 0.0};
  Simulation sim(make_scene(doc), loader);
  double last = 2.0;
  for (int i = 0; i < 10; ++i) {
    sim.step();
    const double u = std::abs(sim.state().v(0, 1) - sim.state().v(0, 0));
    REQUIRE((u <= last || u < 1e-15));  // down to the rounding of v (|v| ~ 0.5)
    last = u;
  }
  CHECK(last < 1e-15);
  // both move with the centre of mass, -2 / 4
  CHECK(std::abs(sim.state().v(0, 0) + 0.5) < 1e-12);
}

TEST_CASE("xpbd: every constraint plugin runs from one scene (blob with area and bending)") {
  // linear_spring, damped_spring, bending and area_pressure as constraints at dt = 1/60, a
  // stiff ring blob falling onto the floor: stays finite, keeps its area within 5%.
  const json doc = {
      {"time", {{"dt", 1.0 / 60.0}, {"duration", 2.0}}},
      {"integrator", "xpbd"},
      {"xpbd", {{"substeps", 8}, {"iterations", 1}}},
      {"backend", "sdf"},
      {"bodies",
       {{{"type", "ring_blob"},
         {"name", "blob"},
         {"center", {0.0, 1.0}},
         {"ring_radius", 0.5},
         {"count", 24},
         {"total_mass", 1.0}}}},
      {"obstacles",
       {{{"id", "floor"},
         {"shape", {{"type", "box"}, {"center", {0.0, -0.5}}, {"half_size", {4.0, 0.5}}}}}}},
      {"forces",
       {{{"type", "gravity"}},
        {{"type", "damped_spring"},
         {"params", {{"ks", 1e5}, {"kd", 10.0}}},
         {"elements", {{"body", "blob"}, {"set", "edges"}}}},
        {{"type", "linear_spring"},
         {"params", {{"k", 1e4}}},
         {"elements", {{"body", "blob"}, {"set", "cross"}}}},
        {{"type", "bending"},
         {"params", {{"k", 10.0}, {"shape", "initial"}}},
         {"elements", {{"body", "blob"}, {"set", "triples"}}}},
        {{"type", "area_pressure"},
         {"params", {{"k", 1e5}}},
         {"elements", {{"body", "blob"}, {"set", "boundary"}}}}}}};
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(make_scene(doc), loader);
  for (uint64_t i = 0; i < sim.scene().steps(); ++i) sim.step();
  const json stats = sim.integrator_stats();
  CHECK(stats["external_forces"].size() == 1);  // gravity
  CHECK(stats["colours"].get<int>() >= 3);
  const State& s = sim.state();
  REQUIRE(s.x.allFinite());
  double area = 0.0;
  const Eigen::Index n = s.x.cols();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Index j = (i + 1) % n;
    area += 0.5 * (s.x(0, i) * s.x(1, j) - s.x(0, j) * s.x(1, i));
  }
  const double a0 = 0.5 * 24 * 0.25 * std::sin(2.0 * M_PI / 24);  // regular 24-gon, r = 0.5
  CHECK(std::abs(area - a0) < 0.05 * a0);
  CHECK(s.x.row(1).minCoeff() > -0.05);  // on the floor, not through it
}

TEST_CASE("xpbd: the scene's settings and their errors name the JSON path") {
  const json good = oscillator("xpbd", 3.0, 0.01, 1.0);
  PluginLoader loader(plugin_search_dirs());
  CHECK(make_scene(good, {"xpbd.substeps=7", "xpbd.iterations=3"}).xpbd.substeps == 7);
  CHECK(make_scene(good, {"xpbd.iterations=3"}).xpbd.iterations == 3);
  REQUIRE_THROWS_WITH(make_scene(good, {"xpbd.substeps=0"}), Contains("xpbd.json: xpbd.substeps") &&
                                                                 Contains("from 1 to 100000") &&
                                                                 Contains("got 0"));
  REQUIRE_THROWS_WITH(make_scene(good, {"xpbd.iterations=1000001"}),
                      Contains("xpbd.iterations") && Contains("got 1000001"));
  REQUIRE_THROWS_WITH(make_scene(good, {"xpbd.iterations=2.5"}),
                      Contains("xpbd.iterations") && Contains("non-negative integer"));
  REQUIRE_THROWS_WITH(make_scene(good, {"xpbd.sweeps=2"}),
                      Contains("xpbd.sweeps") && Contains("unknown key"));
  REQUIRE_THROWS_WITH(make_scene(good, {"xpbd=4"}), Contains("xpbd") && Contains("object"));
  // the settings count: 4 substeps at dt are 4 steps at dt/4 (same bits)
  Simulation a(make_scene(good, {"xpbd.substeps=4"}), loader);
  Simulation b(make_scene(good, {"time.dt=0.0025"}), loader);
  a.step();
  for (int i = 0; i < 4; ++i) b.step();
  CHECK((a.state().x - b.state().x).norm() < 1e-15);
  CHECK(a.integrator_stats()["substeps"] == 4);
}
