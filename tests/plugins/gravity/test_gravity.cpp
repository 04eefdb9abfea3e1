// gravity: uniform field and the pairwise R^α mode (seed, "Gradient of distance to power α").
#include <catch2/catch.hpp>
#include <cmath>

#include "../force_harness.hpp"

using pinsim::test::Force;
using pinsim::test::Particles;

TEST_CASE("uniform: f = m g, pinned particles feel nothing") {
  Particles s(2);
  s.w << 0.5, 0.0;  // m = 2, pinned
  Force f("gravity", {{"g", {1.0, -9.0}}}, s, {0, 1});
  const Eigen::Matrix2Xd out = f.force(s);
  CHECK(out(0, 0) == Approx(2.0));
  CHECK(out(1, 0) == Approx(-18.0));
  CHECK(out.col(1).norm() == 0.0);
}

TEST_CASE("pairwise α = -1, no softening: Newton's |f| = G m1 m2 / R², E = -G m1 m2 / R") {
  Particles s(2);
  s.x.col(1) << 0.0, 2.0;
  s.w << 1.0 / 3.0, 0.5;  // m1 = 3, m2 = 2
  Force f("gravity", {{"mode", "pairwise"}, {"G", 0.5}, {"alpha", -1.0}, {"softening", 0.0}}, s,
          {0, 1});
  const Eigen::Matrix2Xd out = f.force(s);
  // 0.5 * 3 * 2 / 4 = 0.75, attractive: particle 0 pulled up, particle 1 down.
  CHECK(out(1, 0) == Approx(0.75));
  CHECK(out(1, 1) == Approx(-0.75));
  CHECK(f.energy(s) == Approx(-0.5 * 3 * 2 / 2.0));
}

TEST_CASE("pairwise α = 0 is 2D gravity, E = G m m ln R_s, |f| = G m m R / R_s²") {
  Particles s(2);
  s.x.col(1) << 3.0, 0.0;
  Force f("gravity", {{"mode", "pairwise"}, {"alpha", 0.0}, {"softening", 4.0}}, s, {0, 1});
  // R = 3, R_s = 5: |f| = 3 / 25, E = ln 5.
  CHECK(f.force(s)(0, 0) == Approx(3.0 / 25.0));
  CHECK(f.energy(s) == Approx(std::log(5.0)));
}

TEST_CASE("pairwise: a two-body circular orbit keeps its radius") {
  // Equal masses m at distance d: each moves on a circle of radius d/2 with speed
  // v² = G m / (2 d) (centripetal m v²/(d/2) = G m² / d²).
  const double G = 1.0, m = 1.0, d = 1.0, v = std::sqrt(G * m / (2 * d));
  Particles s(2);
  s.x.col(0) << -d / 2, 0;
  s.x.col(1) << d / 2, 0;
  s.v.col(0) << 0, -v;
  s.v.col(1) << 0, v;
  Force f("gravity", {{"mode", "pairwise"}, {"G", G}, {"softening", 0.0}}, s, {0, 1});
  const double period = 2 * M_PI * (d / 2) / v;
  const double dt = period / 2000;
  double worst = 0.0;
  for (int i = 0; i < 4000; ++i) {  // two orbits
    pinsim::test::rk4_step({&f}, s, dt);
    worst = std::max(worst, std::abs((s.x.col(1) - s.x.col(0)).norm() - d));
  }
  CHECK(worst < 1e-9);
}
