// damped_spring: the seed's damped-spring force and the underdamped oscillator's closed form.
#include <catch2/catch.hpp>
#include <cmath>

#include "../force_harness.hpp"

using pinsim::test::Force;
using pinsim::test::Particles;

TEST_CASE("f_i = -(δik - δil) R̂ {ks (R - L) + kd Ṙ}, Ṙ = (v_k - v_l)·R̂") {
  // R = p0 - p1 = (0, 2), R̂ = (0, 1), L = 1, v_k - v_l = (5, -3), Ṙ = -3;
  // ks = 10, kd = 2: f_0 = -(0, 1) (10 * 1 + 2 * -3) = (0, -4), f_1 = (0, 4).
  Particles s(2);
  s.x.col(0) << 1, 2;
  s.x.col(1) << 1, 0;
  s.v.col(0) << 5, -3;
  Force f("damped_spring", {{"ks", 10.0}, {"kd", 2.0}, {"rest_length", 1.0}}, s, {0, 1});
  const Eigen::Matrix2Xd out = f.force(s);
  CHECK(out(0, 0) == Approx(0.0).margin(1e-14));
  CHECK(out(1, 0) == Approx(-4.0));
  CHECK(out(1, 1) == Approx(4.0));
  CHECK(f.energy(s) == Approx(5.0));  // ks/2 (R - L)^2
  // df/dv = -kd R̂R̂ᵀ on the (k, k) block: only the y-y entry, -2.
  const Eigen::MatrixXd kv = f.jacobian(s, 1);
  CHECK(kv(1, 1) == Approx(-2.0));
  CHECK(kv(0, 0) == Approx(0.0).margin(1e-14));
  CHECK(kv(1, 3) == Approx(2.0));
}

TEST_CASE("underdamped two-mass oscillator follows its closed form") {
  // μ ü = -ks u - kd u̇ for u = R - L (the damped force on both masses), so with
  // ω = sqrt(ks/μ), ζ = kd / (2 sqrt(ks μ)) < 1, ωd = ω sqrt(1 - ζ²):
  //   u(t) = e^{-ζωt} (u0 cos ωd t + (u̇0 + ζω u0)/ωd sin ωd t).
  const double ks = 40.0, kd = 0.8, m1 = 2.0, m2 = 0.5, L = 0.7;
  const double mu = m1 * m2 / (m1 + m2), w = std::sqrt(ks / mu);
  const double zeta = kd / (2.0 * std::sqrt(ks * mu)), wd = w * std::sqrt(1 - zeta * zeta);
  REQUIRE(zeta < 0.2);
  Particles s(2);
  s.x.col(0) << 0.3, -0.2;
  const Eigen::Vector2d dir(0.6, 0.8);
  s.x.col(1) = s.x.col(0) + L * dir;
  Force f("damped_spring", {{"ks", ks}, {"kd", kd}}, s, {0, 1});  // L from the initial state
  s.w << 1.0 / m1, 1.0 / m2;
  const double u0 = 0.05, ud0 = 0.3;
  s.x.col(1) = s.x.col(0) + (L + u0) * dir;
  s.v.col(1) = ud0 * dir;  // relative velocity along the spring
  const double dt = 2e-4;
  double worst = 0.0, t = 0.0;
  for (int i = 0; i < 20000; ++i) {  // 4 s, ~ 5 periods, amplitude decays by e^{-ζω 4}
    pinsim::test::rk4_step({&f}, s, dt);
    t += dt;
    const double u = (s.x.col(1) - s.x.col(0)).norm() - L;
    const double exact = std::exp(-zeta * w * t) *
                         (u0 * std::cos(wd * t) + (ud0 + zeta * w * u0) / wd * std::sin(wd * t));
    worst = std::max(worst, std::abs(u - exact));
  }
  CHECK(worst < 1e-8);
  // Energy only decreases: E + kinetic at the end is below the start.
  const double ke = 0.5 * m1 * s.v.col(0).squaredNorm() + 0.5 * m2 * s.v.col(1).squaredNorm();
  CHECK(ke + f.energy(s) < 0.5 * ks * u0 * u0 + 0.5 * ud0 * ud0 * m2);
}

TEST_CASE("the SDK's ConstraintSpring assembles the exact Jacobians of C = R - L") {
  // df/dx from the plugin against the spring's known stiffness with damping at rest (v = 0):
  // K = ks [R̂R̂ᵀ + (1 - L/R)(I - R̂R̂ᵀ)], df_k/dp_k = -K.
  Particles s(2);
  s.x.col(1) << 3, 4;  // R = 5, R̂ = -(0.6, 0.8) for k = 0
  Force f("damped_spring", {{"ks", 2.0}, {"kd", 1.0}, {"rest_length", 2.5}}, s, {0, 1});
  const Eigen::MatrixXd kx = f.jacobian(s, 0);
  const Eigen::Vector2d n(0.6, 0.8);
  const Eigen::Matrix2d nn = n * n.transpose();
  const Eigen::Matrix2d K = 2.0 * (nn + 0.5 * (Eigen::Matrix2d::Identity() - nn));
  CHECK((kx.block<2, 2>(0, 0) + K).norm() < 1e-12);
  CHECK((kx.block<2, 2>(0, 2) - K).norm() < 1e-12);
}

TEST_CASE("damped_spring's Jacobians through the 2x2 block sink match finite differences") {
  // The SDK hands Triplets::add_block's blocks to the host in batches (add_blocks); a host
  // sink without add_blocks gets the same entries one by one. Both must give the same
  // matrices, and those must be the derivatives of the force: central differences
  //   df/dq_j ~ (f(q + e e_j) - f(q - e e_j)) / (2 e), error O(e^2 f''') ~ 1e-9 here.
  // Three particles, two springs sharing particle 1, stretched, turning and moving (so the
  // damping's nonsymmetric term -kd J^T (H v)^T is in df/dx); 100 springs over the same
  // particles make the batch (64 blocks) overflow and hand over more than once.
  Particles s(3);
  s.x.col(0) << 0.1, 0.2;
  s.x.col(1) << 1.3, 0.4;
  s.x.col(2) << 1.1, 1.9;
  std::vector<uint32_t> elements;
  for (int k = 0; k < 50; ++k) elements.insert(elements.end(), {0, 1, 1, 2});
  Force f("damped_spring", {{"ks", 30.0}, {"kd", 1.5}, {"rest_length", 0.8}}, s, elements);
  s.v.col(0) << 0.7, -0.4;
  s.v.col(1) << -0.2, 0.9;
  s.v.col(2) << 0.5, 0.3;
  for (int which = 0; which < 2; ++which) {
    const Eigen::MatrixXd blocks = f.jacobian(s, which), single = f.jacobian(s, which, false);
    CHECK((blocks - single).cwiseAbs().maxCoeff() == 0.0);
    Eigen::MatrixXd fd(6, 6);
    const double e = 1e-6;
    for (int j = 0; j < 6; ++j) {
      Particles p = s, m = s;
      (which == 0 ? p.x : p.v).data()[j] += e;
      (which == 0 ? m.x : m.v).data()[j] -= e;
      const Eigen::Matrix2Xd d = (f.force(p) - f.force(m)) / (2.0 * e);
      fd.col(j) = Eigen::Map<const Eigen::VectorXd>(d.data(), 6);
    }
    INFO("which " << which << "\nblocks\n" << blocks << "\nfd\n" << fd);
    CHECK(blocks.cwiseAbs().maxCoeff() > 1.0);  // not trivially zero
    CHECK((blocks - fd).cwiseAbs().maxCoeff() < 1e-6 * blocks.cwiseAbs().maxCoeff());
  }
}
