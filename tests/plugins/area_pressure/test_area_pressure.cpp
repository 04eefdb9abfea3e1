// area_pressure: the shoelace area, its gradient and the pressure force against closed
// forms on squares; whole-body elements of several lengths; check-plugin in every topology,
// and a broken variant that check-plugin must fail by name.
#include <catch2/catch.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "../force_harness.hpp"
#include "tools/check_layout.hpp"
#include "tools/plugin_check.hpp"

using pinsim::test::Force;
using pinsim::test::Particles;

namespace {

/// Unit square (0,0), (1,0), (1,1), (0,1), counter-clockwise, scaled by s about the origin.
Particles square(double s, bool clockwise = false) {
  Particles p(4);
  const double c[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  for (int i = 0; i < 4; ++i) {
    const int k = clockwise ? (4 - i) % 4 : i;  // (0,0), (0,1), (1,1), (1,0) when clockwise
    p.x.col(i) = s * Eigen::Vector2d(c[k][0], c[k][1]);
  }
  return p;
}

/// One whole-body element holding particles 0..3 (length-prefixed, PINSIM_ARITY_VARIABLE).
const std::vector<uint32_t> kSquare = {4, 0, 1, 2, 3};

const std::vector<std::string> kChecks = {
    "gradient",         "dfdx",       "dfdv",       "momentum", "angular_momentum",
    "rigid_invariance", "degenerate", "dissipation"};

}  // namespace

TEST_CASE("square scaled by s: A = s^2, E = k/2 (s^2 - 1)^2") {
  // Shoelace on the unit square: A = 1/2 sum (x_i y_i+1 - x_i+1 y_i) = 1 = A0 (rest
  // 'initial'); scaled by 1.1: A = 1.21, E = 1000/2 (0.21)^2 = 22.05.
  Force f("area_pressure", {{"k", 1000.0}}, square(1.0), kSquare);
  CHECK(f.energy(square(1.0)) == Approx(0.0).margin(1e-12));
  CHECK(f.energy(square(1.1)) == Approx(22.05));
  CHECK(f.force(square(1.0)).norm() == Approx(0.0).margin(1e-12));
}

TEST_CASE("compressed square: f_i = -k (A - A0) dA/dp_i points outward") {
  // Scaled by 0.9: A - A0 = 0.81 - 1 = -0.19. dA/dp_0 = 1/2 (y_1 - y_3, x_3 - x_1) =
  // 1/2 (0 - 0.9, 0 - 0.9) = (-0.45, -0.45), so f_0 = -1000 (-0.19) (-0.45, -0.45) =
  // (-85.5, -85.5): away from the centre. By symmetry every corner gets 85.5 sqrt 2.
  Force f("area_pressure", {{"k", 1000.0}}, square(1.0), kSquare);
  const Eigen::Matrix2Xd out = f.force(square(0.9));
  CHECK(out(0, 0) == Approx(-85.5));
  CHECK(out(1, 0) == Approx(-85.5));
  CHECK(out(0, 2) == Approx(85.5));  // corner (0.9, 0.9)
  CHECK(out(1, 2) == Approx(85.5));
  CHECK(out.rowwise().sum().norm() == Approx(0.0).margin(1e-12));  // internal: sum f = 0
}

TEST_CASE("rest 'value' keeps the ring's orientation: a clockwise ring gets A0 = -rest_area") {
  // Clockwise unit square: A = -1; rest_area 2 gives A0 = -2, E = 1000/2 (-1 + 2)^2 = 500,
  // and the force inflates it: dA/dp_0 = 1/2 (y_1 - y_3, x_3 - x_1) = (0.5, 0.5) with
  // p_1 = (0, 1), p_3 = (1, 0), so f_0 = -1000 (1) (0.5, 0.5) = (-500, -500), outward.
  const Particles cw = square(1.0, true);
  Force f("area_pressure", {{"k", 1000.0}, {"rest", "value"}, {"rest_area", 2.0}}, cw, kSquare);
  CHECK(f.energy(cw) == Approx(500.0));
  const Eigen::Matrix2Xd out = f.force(cw);
  CHECK(out(0, 0) == Approx(-500.0));
  CHECK(out(1, 0) == Approx(-500.0));
}

TEST_CASE("rings of different lengths in one instance: each keeps its own rest area") {
  // A triangle (particles 0-2) and a square (3-6). Moving the square rigidly changes
  // nothing (A is translation invariant); doubling the triangle's size loads only it.
  Particles p(7);
  p.x.col(0) = Eigen::Vector2d(0, 0);
  p.x.col(1) = Eigen::Vector2d(1, 0);
  p.x.col(2) = Eigen::Vector2d(0, 1);
  for (int i = 0; i < 4; ++i) p.x.col(3 + i) = square(1.0).x.col(i) + Eigen::Vector2d(3, 0);
  // Length-prefixed: the triangle (3; 0, 1, 2), then the square (4; 3, 4, 5, 6).
  Force f("area_pressure", {{"k", 10.0}}, p, {3, 0, 1, 2, 4, 3, 4, 5, 6});
  Particles q = p;
  for (int i = 3; i < 7; ++i) q.x.col(i) += Eigen::Vector2d(-1.5, 2.0);
  CHECK(f.energy(q) == Approx(0.0).margin(1e-12));
  for (int i = 0; i < 3; ++i) q.x.col(i) *= 2.0;
  // Triangle: A = 1/2 -> 2, E = 10/2 (1.5)^2 = 11.25; the square's particles feel nothing.
  CHECK(f.energy(q) == Approx(11.25));
  const Eigen::Matrix2Xd out = f.force(q);
  CHECK(out.rightCols(4).norm() == Approx(0.0).margin(1e-12));
  CHECK(out.leftCols(3).norm() > 1.0);
}

TEST_CASE("an element of fewer than 3 particles is refused, naming it") {
  try {  // element 0: the square; element 1: two particles
    Force f("area_pressure", {}, square(1.0), {4, 0, 1, 2, 3, 2, 0, 1});
    FAIL("created");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()).find("element 1 has 2 particle(s)") != std::string::npos);
  }
}

TEST_CASE("check-plugin passes area_pressure in every topology, with and without damping") {
  pinsim::PluginLoader loader(pinsim::plugin_search_dirs());
  const auto p = loader.load("area_pressure");
  for (const nlohmann::json& params :
       {nlohmann::json{{"k", 1000.0}}, nlohmann::json{{"k", 50.0}, {"kd", 3.0}},
        nlohmann::json{{"k", 200.0}, {"rest", "value"}, {"rest_area", 0.5}}}) {
    for (const std::string& topology : pinsim::check_topologies()) {
      pinsim::CheckOptions o;
      o.params = params;
      o.topology = topology;
      const pinsim::CheckReport r = pinsim::check_force_plugin(*p, o);
      INFO(params.dump() << "\n" << pinsim::format_report(r));
      CHECK(r.passed());
      for (const auto& name : kChecks) {
        REQUIRE(r.find(name) != nullptr);
        CHECK(r.find(name)->status == pinsim::CheckStatus::Pass);
      }
    }
  }
}

TEST_CASE("check-plugin fails the broken variant (no curvature term in df/dx) on dfdx") {
  const auto p =
      pinsim::load_plugin_file(std::string(PINSIM_TEST_FIXTURE_DIR) + "/libfixture_wrong_area.so");
  for (const std::string& topology : pinsim::check_topologies()) {
    pinsim::CheckOptions o;
    o.topology = topology;
    const pinsim::CheckReport r = pinsim::check_force_plugin(*p, o);
    const std::string text = pinsim::format_report(r);
    INFO(topology << "\n" << text);
    CHECK_FALSE(r.passed());
    CHECK(r.find("dfdx")->status == pinsim::CheckStatus::Fail);
    CHECK(text.find("FAIL  dfdx") != std::string::npos);
    CHECK(text.find(")/d(particle ") != std::string::npos);  // names the entry
    CHECK(r.find("gradient")->status == pinsim::CheckStatus::Pass);
    CHECK(r.find("momentum")->status == pinsim::CheckStatus::Pass);
  }
}
