// linear_spring: the seed's formulas and a two-mass oscillator against ω = sqrt(k/μ).
#include <catch2/catch.hpp>
#include <cmath>

#include "../force_harness.hpp"

using pinsim::test::Force;
using pinsim::test::Particles;

namespace {
Particles pair(Eigen::Vector2d a, Eigen::Vector2d b) {
  Particles p(2);
  p.x.col(0) = a;
  p.x.col(1) = b;
  return p;
}
}  // namespace

TEST_CASE("finite rest length: f_k = -k (R - L) R̂ = -f_l") {
  // Seed, "Linear spring with finite rest-length, L". R = p0 - p1 = (-2, 0), L = 0.5, k = 10:
  // f_0 = -10 (2 - 0.5) (-1, 0) = (15, 0), f_1 = (-15, 0); E = 10/2 1.5^2 = 11.25.
  const Particles s = pair({0, 0}, {2, 0});
  Force f("linear_spring", {{"k", 10.0}, {"rest_length", 0.5}}, s, {0, 1});
  const Eigen::Matrix2Xd out = f.force(s);
  CHECK(out(0, 0) == Approx(15.0));
  CHECK(out(1, 0) == Approx(0.0).margin(1e-14));
  CHECK(out(0, 1) == Approx(-15.0));
  CHECK(f.energy(s) == Approx(11.25));
}

TEST_CASE("zero rest length: f_k = -k (p_k - p_l), E = k/2 |p_k - p_l|^2") {
  // Seed, "Zero rest-length spring": p0 - p1 = (1, -2), k = 4: f_0 = (-4, 8), E = 2 * 5 = 10.
  const Particles s = pair({1, 0}, {0, 2});
  Force f("linear_spring", {{"k", 4.0}, {"rest_length", 0.0}}, s, {0, 1});
  const Eigen::Matrix2Xd out = f.force(s);
  CHECK(out(0, 0) == Approx(-4.0));
  CHECK(out(1, 0) == Approx(8.0));
  CHECK((out.col(0) + out.col(1)).norm() == Approx(0.0).margin(1e-14));
  CHECK(f.energy(s) == Approx(10.0));
  // The zero-rest-length spring stays linear through R = 0: f = 0 and df/dx = -k I there.
  const Particles c = pair({1, 1}, {1, 1});
  CHECK(f.force(c).cwiseAbs().maxCoeff() == 0.0);
  CHECK(f.jacobian(c, 0)(0, 0) == Approx(-4.0));
}

TEST_CASE("rest length defaults to the initial configuration") {
  const Particles init = pair({0, 0}, {0.3, 0.4});  // |R| = 0.5
  Force f("linear_spring", {{"k", 10.0}}, init, {0, 1});
  CHECK(f.force(init).cwiseAbs().maxCoeff() == Approx(0.0).margin(1e-13));
  const Particles moved = pair({0, 0}, {0, 1.5});  // stretched by 1: |f| = 10
  CHECK(f.force(moved)(1, 1) == Approx(-10.0));
}

TEST_CASE("two-mass oscillator: period 2π/ω, ω = sqrt(k/μ), μ = m1 m2/(m1 + m2)") {
  // Relative coordinate u = R - L obeys μ ü = -k u (seed spring force, Newton's law on both
  // masses), so u oscillates with period T = 2π sqrt(μ/k). Integrated with RK4 (dt = T/4000).
  const double k = 50.0, m1 = 1.0, m2 = 3.0, L = 1.0;
  const double mu = m1 * m2 / (m1 + m2), T = 2.0 * M_PI * std::sqrt(mu / k);
  Particles s = pair({0, 0}, {L, 0});
  Force f("linear_spring", {{"k", k}}, s, {0, 1});
  s.w << 1.0 / m1, 1.0 / m2;
  s.x(0, 1) = L + 0.1;  // stretch by 0.1
  const double dt = T / 4000.0;
  std::vector<double> crossings;
  double u_prev = 0.1, t = 0.0;
  while (t < 3.6 * T) {
    pinsim::test::rk4_step({&f}, s, dt);
    t += dt;
    const double u = (s.x.col(1) - s.x.col(0)).norm() - L;
    if (u_prev > 0 && u <= 0) crossings.push_back(t - dt * u / (u - u_prev));  // interpolate
    u_prev = u;
  }
  REQUIRE(crossings.size() >= 3);
  const double measured = (crossings.back() - crossings.front()) / (crossings.size() - 1);
  CHECK(std::abs(measured - T) / T < 1e-6);
  // The centre of mass stays at rest: internal forces carry no net momentum.
  const Eigen::Vector2d p = s.v.col(0) * m1 + s.v.col(1) * m2;
  CHECK(p.norm() < 1e-12);
}
