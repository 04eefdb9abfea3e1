// bending: the seed's closed-form hair-bending forces, the rest-angle variant, and a stiff
// cantilever strand at rest under gravity keeping its shape.
#include <catch2/catch.hpp>
#include <cmath>

#include "../force_harness.hpp"

using pinsim::test::Force;
using pinsim::test::Particles;

namespace {
Particles triple(Eigen::Vector2d p0, Eigen::Vector2d p1, Eigen::Vector2d p2) {
  Particles s(3);
  s.x.col(0) = p0;
  s.x.col(1) = p1;
  s.x.col(2) = p2;
  return s;
}
}  // namespace

TEST_CASE("seed closed form: f0 = -k/(2a)(b̂ - â(â·b̂)), f2 = k/(2b)(â - b̂(â·b̂)), f1 = -f0-f2") {
  // a = p1 - p0 = (2, 0), b = p2 - p1 = (0, 1) (a right angle), k = 4:
  // â·b̂ = 0, f0 = -4/4 (0, 1) = (0, -1), f2 = 4/2 (1, 0) = (2, 0), f1 = (-2, 1); E = 0.
  const Particles s = triple({0, 0}, {2, 0}, {2, 1});
  Force f("bending", {{"k", 4.0}}, s, {0, 1, 2});
  const Eigen::Matrix2Xd out = f.force(s);
  CHECK(out(0, 0) == Approx(0.0).margin(1e-14));
  CHECK(out(1, 0) == Approx(-1.0));
  CHECK(out(0, 2) == Approx(2.0));
  CHECK(out(1, 2) == Approx(0.0).margin(1e-14));
  CHECK(out(0, 1) == Approx(-2.0));
  CHECK(out(1, 1) == Approx(1.0));
  CHECK(f.energy(s) == Approx(0.0).margin(1e-14));
  // Straight: E = -k/2, the minimum, no force.
  const Particles straight = triple({0, 0}, {1, 1}, {3, 3});
  CHECK(f.energy(straight) == Approx(-2.0));
  CHECK(f.force(straight).cwiseAbs().maxCoeff() < 1e-14);
}

TEST_CASE("rest-angle variant: E = -k/2 cos(θ - θ0) is minimal at θ0") {
  const double th0 = 0.6;
  const Particles init = triple({0, 0}, {1, 0}, {1 + std::cos(th0), std::sin(th0)});
  Force fi("bending", {{"k", 2.0}, {"shape", "initial"}}, init, {0, 1, 2});
  Force fa("bending", {{"k", 2.0}, {"shape", "angle"}, {"rest_angle", th0}}, init, {0, 1, 2});
  for (const Force* f : {&fi, &fa}) {
    CHECK(f->force(init).cwiseAbs().maxCoeff() < 1e-14);
    CHECK(f->energy(init) == Approx(-1.0));
  }
  // At θ = θ0 + π/2, cos(θ - θ0) = 0: E = 0, while the flat shape has E = -cos(θ0 + π/2).
  const double th = th0 + M_PI / 2;
  const Particles bent = triple({0, 0}, {1, 0}, {1 + std::cos(th), std::sin(th)});
  CHECK(fi.energy(bent) == Approx(0.0).margin(1e-14));
  Force flat("bending", {{"k", 2.0}}, init, {0, 1, 2});
  CHECK(flat.energy(bent) == Approx(-std::cos(th)));
  // The restoring force on p2 turns the joint back toward θ0: torque about p1 is -k/2 sin(θ-θ0).
  const Eigen::Matrix2Xd f = fi.force(bent);
  const Eigen::Vector2d b = bent.x.col(2) - bent.x.col(1);
  CHECK(b.x() * f(1, 2) - b.y() * f(0, 2) == Approx(-1.0));
}

TEST_CASE("stiff cantilever strand at rest under gravity keeps its shape") {
  // A horizontal strand of n particles, the first two pinned (inverse mass 0), edges as
  // damped springs, bending with flat rest shape, gravity, and a small drag to settle.
  // Static small-angle balance about joint j (the part beyond j is held by the bending torque
  // k/2 sin θ_j, springs pass through p_j): k/2 θ_j = Σ_{i>j} m g (x_i - x_j).
  // The predicted sag is y_i = -Σ_{1<=j<i} θ_j (x_i - x_j).
  const int n = 10;
  const double l = 0.1, m = 0.01, g = 9.81, kb = 300.0;
  Particles s(n);
  std::vector<uint32_t> edges, triples;
  for (int i = 0; i < n; ++i) {
    s.x.col(i) << i * l, 0.0;
    s.w[i] = i < 2 ? 0.0 : 1.0 / m;
    if (i + 1 < n) edges.insert(edges.end(), {uint32_t(i), uint32_t(i + 1)});
    if (i + 2 < n) triples.insert(triples.end(), {uint32_t(i), uint32_t(i + 1), uint32_t(i + 2)});
  }
  std::vector<uint32_t> all(n);
  for (int i = 0; i < n; ++i) all[i] = i;
  Force springs("damped_spring", {{"ks", 1e4}, {"kd", 0.5}}, s, edges);
  Force bend("bending", {{"k", kb}}, s, triples);
  Force grav("gravity", {{"g", {0.0, -g}}}, s, all);
  const double dt = 5e-5;
  for (int step = 0; step < 60000; ++step)  // 3 s; amplitudes decay as e^{-c t/(2m)} = e^{-30}
    pinsim::test::symplectic_euler_step({&springs, &bend, &grav}, s, dt, 0.2);

  std::vector<double> theta(n, 0.0), predicted(n, 0.0);
  for (int j = 1; j < n - 1; ++j) {
    double mom = 0.0;
    for (int i = j + 1; i < n; ++i) mom += m * g * (i - j) * l;
    theta[j] = 2.0 * mom / kb;
  }
  for (int i = 2; i < n; ++i)
    for (int j = 1; j < i; ++j) predicted[i] -= theta[j] * (i - j) * l;
  double shape_dev = 0.0;
  for (int i = 0; i < n; ++i) shape_dev = std::max(shape_dev, std::abs(s.x(1, i)));
  // Keeps its shape: the sag is below 1% of the strand's length ...
  CHECK(shape_dev < 0.01 * (n - 1) * l);
  // ... and is the static small-angle sag, not residual motion (within 5%).
  CHECK(s.x(1, n - 1) == Approx(predicted[n - 1]).epsilon(0.05));
  CHECK(s.v.cwiseAbs().maxCoeff() < 1e-4);
}

TEST_CASE("length-scaled stiffness: k / l with l the triple's mean initial edge length") {
  // Edges 1 and 3 initially: l = 2, k = 4 -> k_e = 2, so a straight triple has E = -k_e/2 = -1
  // and the right-angle forces are half the unscaled ones (f0 = -k_e/(2a) b̂).
  const Particles init = triple({0, 0}, {1, 0}, {4, 0});
  Force f("bending", {{"k", 4.0}, {"length_scaled", true}}, init, {0, 1, 2});
  CHECK(f.energy(init) == Approx(-1.0));
  const Particles bent = triple({0, 0}, {1, 0}, {1, 3});
  CHECK(f.force(bent)(1, 0) == Approx(-1.0));  // -2/(2*1) * (0, 1)
}
