// Implicit Euler's linear solve: the warm-started, Jacobi-preconditioned conjugate gradients
// against the closed-form backward Euler step of one damped spring, its solver figures, a
// forced fallback to sparse LU (reported, and giving the same answer), and a damped chain
// whose system is nonsymmetric (BiCGSTAB, agreeing with sparse LU on A itself).
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/integrators.hpp"
#include "core/jacobian_entries.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "test_support.hpp"

using namespace pinsim;
using nlohmann::json;

namespace {

Scene make_scene(const json& doc) { return parse_scene(doc.dump(), "solver", "."); }

// A chain of springs pinned at one end, starting straight along x and falling under gravity
// (each step one linear solve of 2 x 12 dofs). Undamped (kd = 0) A is symmetric; damped, the
// springs turn as the chain swings down (a motion sideways to them) and a damped spring's
// df/dx has the nonsymmetric term -kd J^T (H v)^T.
json chain(double kd = 0.0) {
  json doc = json::parse(R"({"time": {"dt": 0.01, "duration": 0.2},
    "integrator": "implicit_euler",
    "bodies": [{"type": "strand", "name": "chain", "root": [0, 0], "direction": [1, 0],
                "count": 12, "segment_length": 0.1, "mass": 0.1, "pin": [0]}],
    "forces": [{"type": "gravity"},
               {"type": "damped_spring", "params": {"ks": 500, "kd": 0},
                "elements": {"body": "chain", "set": "edges"}}]})");
  doc["forces"][1]["params"]["kd"] = kd;
  return doc;
}

/// Steps `sim` with its own integrator and `other` with `forced` (as Simulation::step does
/// around its integrator: the time after the step, which forces may depend on).
void step_both(Simulation& sim, Simulation& other, Integrator& forced, int steps) {
  for (int n = 0; n < steps; ++n) {
    sim.step();
    forced.step(other, 0.01);
    other.state().t = static_cast<double>(n + 1) * 0.01;
  }
}

}  // namespace

TEST_CASE("implicit Euler: a damped spring along its axis follows the closed-form step") {
  // Particle 1 (mass m) on the x axis at distance x from pinned particle 0, velocity v
  // along the axis, spring ks, damping kd, rest length L. Along the axis
  // f = -ks (x - L) - kd v, df/dx = -ks, df/dv = -kd (the transverse terms vanish: the
  // motion stays on the axis), so the linearized backward Euler step (Baraff & Witkin 1998,
  // eq. 6) is exact and solved in closed form:
  //   (m + h kd + h^2 ks) dv = h (f_n - h ks v_n),  v_{n+1} = v_n + dv,  x_{n+1} = x_n + h v_{n+1}.
  const double m = 0.3, ks = 40.0, kd = 0.7, L = 0.5, h = 0.02;
  const json doc = {{"time", {{"dt", h}, {"duration", 1.0}}},
                    {"integrator", "implicit_euler"},
                    {"backend", {{"name", "none"}}},
                    {"particles",
                     {{{"x", {0.0, 0.0}}, {"pinned", true}},
                      {{"x", {0.8, 0.0}}, {"v", {0.4, 0.0}}, {"mass", m}}}},
                    {"forces",
                     {{{"type", "damped_spring"},
                       {"params", {{"ks", ks}, {"kd", kd}, {"rest_length", L}}},
                       {"elements", {{0, 1}}}}}}};
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(make_scene(doc), loader);
  double x = 0.8, v = 0.4;
  for (int n = 0; n < 50; ++n) {
    const double f = -ks * (x - L) - kd * v;
    v += h * (f - h * ks * v) / (m + h * kd + h * h * ks);
    x += h * v;
    sim.step();
    INFO("step " << n + 1);
    REQUIRE(sim.state().x(0, 1) == Approx(x).epsilon(1e-12).margin(1e-14));
    REQUIRE(sim.state().v(0, 1) == Approx(v).epsilon(1e-12).margin(1e-14));
    REQUIRE(sim.state().x(1, 1) == 0.0);
  }
  const json st = sim.integrator_stats();
  CHECK(st["linear_solves"] == 50);
  CHECK(st["lu_fallbacks"] == 0);
  CHECK(st["preconditioner"] == "jacobi");
}

TEST_CASE("implicit Euler: solver figures are sane and a forced LU fallback is reported") {
  PluginLoader loader(plugin_search_dirs());
  Simulation cg(make_scene(chain()), loader), lu(make_scene(chain()), loader);
  // One CG iteration cannot reach a relative residual of 1e-12 on this system (24 dofs,
  // springs coupling neighbours): the solves fall back to sparse LU.
  auto forced = make_implicit_euler(ImplicitEulerOptions{1});
  const int steps = 20;
  step_both(cg, lu, *forced, steps);
  const json a = cg.integrator_stats(), b = forced->stats();
  INFO(a.dump() << "\n" << b.dump());
  CHECK(a["linear_solves"] == steps);
  CHECK(a["lu_fallbacks"] == 0);
  CHECK(a["cg_iterations_max"].get<int>() >= 1);
  CHECK(a["cg_iterations_max"].get<int>() <= 100);
  CHECK(a["cg_iterations_per_solve"].get<double>() <= a["cg_iterations_max"].get<double>());
  CHECK(a["worst_relative_residual"].get<double>() <= 1e-12);
  CHECK(a["bicgstab_solves"] == 0);  // undamped: A is symmetric, CG throughout
  CHECK(b["linear_solves"] == steps);
  // All but the first: the chain starts straight and at rest, where the springs are at
  // their rest lengths, K has no y part and A restricted to y is M, which Jacobi-CG solves
  // in its one iteration.
  CHECK(b["lu_fallbacks"] == steps - 1);
  CHECK(b["cg_iterations_max"].get<int>() <= 1);
  CHECK(b["worst_relative_residual"].get<double>() <= 1e-8);
  // Both solve the same systems to 1e-12 (CG) and rounding (LU): the chains agree closely.
  for (Eigen::Index i = 0; i < cg.state().x.cols(); ++i)
    for (int d = 0; d < 2; ++d) {
      CHECK(lu.state().x(d, i) == Approx(cg.state().x(d, i)).epsilon(1e-9).margin(1e-12));
      CHECK(lu.state().v(d, i) == Approx(cg.state().v(d, i)).epsilon(1e-8).margin(1e-10));
    }
}

TEST_CASE("implicit Euler: a damped chain's nonsymmetric system is solved, not its transpose") {
  // Damped, the chain's A = M - h D - h^2 K is nonsymmetric once the springs turn (-kd J^T
  // (H v)^T in df/dx). The iterative solve must be of A itself: it agrees with sparse LU of
  // the same A (forced by a one-iteration limit). Before the fix CG was used, which for a
  // column-major matrix with Lower|Upper multiplies by A^T: the two runs differed by about
  // 2 % after 20 steps.
  PluginLoader loader(plugin_search_dirs());
  Simulation it(make_scene(chain(2.0)), loader), lu(make_scene(chain(2.0)), loader);
  auto forced = make_implicit_euler(ImplicitEulerOptions{1});
  const int steps = 20;
  step_both(it, lu, *forced, steps);
  const json a = it.integrator_stats(), b = forced->stats();
  INFO(a.dump() << "\n" << b.dump());
  CHECK(a["linear_solves"] == steps);
  CHECK(a["lu_fallbacks"] == 0);
  // The first step starts at rest (v = 0: the nonsymmetric term vanishes), the others not.
  CHECK(a.value("bicgstab_solves", 0) == steps - 1);
  CHECK(a["worst_relative_residual"].get<double>() <= 1e-12);
  CHECK(b["lu_fallbacks"] == steps - 1);
  // The chain swings down: a motion well away from its starting line.
  CHECK(it.state().x(1, 11) < -0.1);
  for (Eigen::Index i = 0; i < it.state().x.cols(); ++i)
    for (int d = 0; d < 2; ++d) {
      INFO("particle " << i << ", component " << d);
      CHECK(lu.state().x(d, i) == Approx(it.state().x(d, i)).epsilon(1e-9).margin(1e-12));
      CHECK(lu.state().v(d, i) == Approx(it.state().v(d, i)).epsilon(1e-9).margin(1e-10));
    }
}

TEST_CASE("JacobianEntries keeps single entries and 2x2 blocks in the order they came") {
  // abi.h: block k at particles (i, j) = (p[2k], p[2k + 1]) with values v[4k .. 4k + 3]
  // column-major is the four entries (2i, 2j) v0, (2i, 2j + 1) v2, (2i + 1, 2j) v1,
  // (2i + 1, 2j + 1) v3, row by row; implicit Euler sums them in that order.
  JacobianEntries e;
  const pinsim_triplet_sink sink = e.sink();
  sink.add(sink.context, 0, 1, 1.5);
  const uint32_t p[] = {2, 3, 0, 4};
  const double v[] = {1, 2, 3, 4, 5, 6, 7, 8};
  sink.add_blocks(sink.context, p, v, 1);
  sink.add_blocks(sink.context, p + 2, v + 4, 1);
  sink.add(sink.context, 9, 8, -2.0);
  sink.add_blocks(sink.context, p, v, 0);  // nothing
  REQUIRE(e.runs.size() == 3);
  REQUIRE(e.entries() == 10);
  std::vector<Eigen::Triplet<double>> t;
  e.append_triplets(t);
  const std::vector<std::array<double, 3>> want = {{0, 1, 1.5}, {4, 6, 1}, {4, 7, 3}, {5, 6, 2},
                                                   {5, 7, 4},   {0, 8, 5}, {0, 9, 7}, {1, 8, 6},
                                                   {1, 9, 8},   {9, 8, -2}};
  REQUIRE(t.size() == want.size());
  for (std::size_t k = 0; k < t.size(); ++k) {
    INFO("entry " << k);
    CHECK(t[k].row() == want[k][0]);
    CHECK(t[k].col() == want[k][1]);
    CHECK(t[k].value() == want[k][2]);
  }
  e.clear();
  CHECK(e.entries() == 0);
  CHECK(e.runs.empty());
}

TEST_CASE("implicit Euler: a force assembled into its own copy of A gives A to rounding") {
  // A 60 x 60 sheet (top row pinned) with two damped_spring forces, edges (7,080 springs,
  // 56,640 Jacobian entries) and shears (6,962 springs, 55,696 entries), both concurrent
  // (PINSIM_CAP_CONCURRENT). With the default own_group_entries (16,384) the shears add
  // their -h^2 K, -h D and K v0 into a copy of their own (on a second thread if there is one)
  // and that copy is added to A afterwards; with the threshold above every force's count
  // all entries go into A one after another. The same linear algebra summed in another
  // order: the states must agree to rounding (|dx| <= 1e-12 of the sheet's size), and the
  // sheet must have moved (so the comparison compares something).
  json doc = json::parse(R"({"time": {"dt": 0.001, "duration": 1.0},
    "integrator": "implicit_euler", "backend": {"name": "none"},
    "bodies": [{"type": "grid_blob", "name": "sheet", "origin": [0, 0], "nx": 60, "ny": 60,
                "spacing": 0.01, "total_mass": 3.6, "radius": 0.002}],
    "forces": [{"type": "gravity", "params": {"g": [0, -9.81]}},
               {"type": "damped_spring", "params": {"ks": 50, "kd": 0.01},
                "elements": {"body": "sheet", "set": "edges"}},
               {"type": "damped_spring", "params": {"ks": 20, "kd": 0.005},
                "elements": {"body": "sheet", "set": "shear"}}]})");
  json pin = json::array();
  for (int i = 0; i < 60; ++i) pin.push_back(59 * 60 + i);
  doc["bodies"][0]["pin"] = pin;
  const Scene scene = make_scene(doc);
  PluginLoader loader(plugin_search_dirs());
  Simulation apart(scene, loader), together(scene, loader);
  ImplicitEulerOptions one_group;
  one_group.own_group_entries = static_cast<std::size_t>(-1);
  const auto ia = make_implicit_euler(), ib = make_implicit_euler(one_group);
  for (int n = 0; n < 20; ++n) {
    ia->step(apart, 0.001);
    ib->step(together, 0.001);
    apart.state().t = together.state().t = static_cast<double>(n + 1) * 0.001;
  }
  CHECK(ia->stats()["assembly_groups"] == 2);
  CHECK(ib->stats()["assembly_groups"] == 1);
  // the steady path (entries streamed into the pattern) ran, not a rebuild every step
  CHECK(ia->stats()["pattern_builds"] == 1);
  CHECK(ib->stats()["pattern_builds"] == 1);
  const Eigen::Matrix2Xd& xa = apart.state().x;
  const Eigen::Matrix2Xd& xb = together.state().x;
  const double moved = (xa - scene.initial_state().x).cwiseAbs().maxCoeff();
  const double diff = (xa - xb).cwiseAbs().maxCoeff();
  INFO("moved " << moved << ", states differ by " << diff);
  CHECK(moved > 1e-4);  // 20 ms of free fall: g t^2 / 2 ~ 2 mm below the pinned row
  CHECK(diff <= 1e-12 * 0.6);
}
