// The adjoint of a drift through its impacts, against central differences of a reference
// drift (reference_drift.hpp: exact times of impact) and closed forms.
#include <catch2/catch.hpp>
#include <cmath>
#include <vector>

#include "gradients/drift_adjoint.hpp"
#include "reference_drift.hpp"

using namespace pinsim::grad;
using namespace pinsim::grad::testing;

namespace {

struct Scenario {
  std::vector<RefObstacle> obs;
  RefDiscs discs;
  double depth_min = 1e-5;
  double t0 = 0.0, h = 0.01;
};

struct Out {
  Eigen::Matrix2Xd x, v;
  DriftTape tape;
};

Out run(const Scenario& sc) {
  const std::size_t n = sc.discs.x.size();
  Out o;
  o.tape.t0 = sc.t0;
  o.tape.h = sc.h;
  o.tape.x_in.resize(2, static_cast<Eigen::Index>(n));
  o.tape.v_in.resize(2, static_cast<Eigen::Index>(n));
  o.tape.inv_mass.resize(static_cast<Eigen::Index>(n));
  std::vector<std::vector<std::pair<double, Vec2>>> changes(n);
  std::vector<std::vector<std::pair<int64_t, uint8_t>>> ids(n);
  if (n > 1) ref_pairs(sc.discs, sc.h, o.tape.pairs, changes, ids);
  o.x.resize(2, static_cast<Eigen::Index>(n));
  o.v.resize(2, static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<Eigen::Index>(i);
    o.tape.x_in.col(c) = sc.discs.x[i];
    o.tape.v_in.col(c) = sc.discs.v[i];
    o.tape.inv_mass[c] = sc.discs.w[i];
    Vec2 x = sc.discs.x[i], v = sc.discs.v[i];
    if (sc.discs.w[i] > 0.0)
      ref_drift(sc.obs, sc.discs.r[i] + sc.depth_min, sc.t0, sc.h, x, v, static_cast<uint32_t>(i),
                &o.tape.impacts, changes[i], ids[i]);
    o.x.col(c) = x;
    o.v.col(c) = v;
  }
  return o;
}

/// The scalar a.x_out + b.v_out of a run.
double functional(const Out& o, const Eigen::Matrix2Xd& a, const Eigen::Matrix2Xd& b) {
  return (a.array() * o.x.array()).sum() + (b.array() * o.v.array()).sum();
}

/// Checks every input's adjoint against central differences of the functional, relative
/// to the largest derivative, within tol.
void check_against_fd(const Scenario& sc, double tol, std::size_t min_impacts) {
  const Out base = run(sc);
  REQUIRE(base.tape.impacts.size() >= min_impacts);
  const Eigen::Index n = static_cast<Eigen::Index>(sc.discs.x.size());
  Eigen::Matrix2Xd a(2, n), b(2, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    a.col(i) = Vec2(0.3 + 0.1 * i, -0.7 + 0.2 * i);
    b.col(i) = Vec2(0.11 - 0.05 * i, 0.23);
  }
  Eigen::Matrix2Xd gx = a, gv = b;
  MaterialGrad mg;
  drift_adjoint(base.tape, gx, gv, nullptr, mg);
  std::vector<double> adj, fd;
  const double eps = 1e-7;
  auto diff = [&](auto&& perturb) {
    Scenario p = sc, m = sc;
    perturb(p, eps);
    perturb(m, -eps);
    return (functional(run(p), a, b) - functional(run(m), a, b)) / (2.0 * eps);
  };
  for (Eigen::Index i = 0; i < n; ++i)
    for (int c = 0; c < 2; ++c) {
      const auto k = static_cast<std::size_t>(i);
      if (!(sc.discs.w[k] > 0.0)) continue;
      adj.push_back(gx(c, i));
      fd.push_back(diff([&](Scenario& s, double d) { s.discs.x[k][c] += d; }));
      adj.push_back(gv(c, i));
      fd.push_back(diff([&](Scenario& s, double d) { s.discs.v[k][c] += d; }));
    }
  for (std::size_t k = 0; k < sc.obs.size(); ++k) {
    const auto o = static_cast<int64_t>(k);
    adj.push_back(MaterialGrad::at(mg.restitution, o));
    fd.push_back(diff([&](Scenario& s, double d) { s.obs[k].e += d; }));
    if (sc.obs[k].mu > 0.0) {
      adj.push_back(MaterialGrad::at(mg.friction, o));
      fd.push_back(diff([&](Scenario& s, double d) { s.obs[k].mu += d; }));
    }
    adj.push_back(MaterialGrad::at(mg.kick, o));
    fd.push_back(diff([&](Scenario& s, double d) { s.obs[k].kick += d; }));
  }
  if (!base.tape.pairs.empty()) {
    adj.push_back(mg.pair_restitution);
    fd.push_back(diff([&](Scenario& s, double d) { s.discs.e += d; }));
  }
  double scale = 0.0;
  for (double f : fd) scale = std::max(scale, std::abs(f));
  for (std::size_t k = 0; k < adj.size(); ++k) {
    INFO("input " << k << ": adjoint " << adj[k] << ", central difference " << fd[k]);
    CHECK(std::abs(adj[k] - fd[k]) <= tol * scale);
  }
}

}  // namespace

// Ball on a floor y = 0 (offset c = r + depth_min), e < 1, hitting within the drift: with the
// time of impact tau = (y0 - c) / -vy, y1 = c - e (y0 + vy h - c), vy1 = -e vy, so
//   dy1/dy0 = -e, dy1/dvy = -e h, dvy1/dvy = -e, dy1/de = -(y0 + vy h - c), dvy1/de = -vy,
// and x moves freely (dx1/dvx = h). Without the split at tau (DiffTaichi, 2020) dy1/dy0 is +1.
TEST_CASE("drift adjoint: ball bouncing on a floor, closed form", "[gradients][drift]") {
  Scenario sc;
  RefObstacle floor;
  floor.e = 0.6;
  sc.obs = {floor};
  sc.discs.x = {Vec2(0.2, 0.05)};
  sc.discs.v = {Vec2(0.5, -8.0)};
  sc.discs.r = {0.01};
  sc.discs.w = {1.0};
  const Out o = run(sc);
  REQUIRE(o.tape.impacts.size() == 1);
  const double c = 0.01 + sc.depth_min, e = 0.6, y0 = 0.05, vy = -8.0, h = sc.h;
  CHECK(o.x(1, 0) == Approx(c - e * (y0 + vy * h - c)).epsilon(1e-12));
  auto grad_of = [&](int row_x, int row_v, Eigen::Matrix2Xd& gx, Eigen::Matrix2Xd& gv,
                     MaterialGrad& mg) {
    gx.setZero(2, 1);
    gv.setZero(2, 1);
    if (row_x >= 0) gx(row_x, 0) = 1.0;
    if (row_v >= 0) gv(row_v, 0) = 1.0;
    drift_adjoint(o.tape, gx, gv, nullptr, mg);
  };
  Eigen::Matrix2Xd gx, gv;
  MaterialGrad mg;
  grad_of(1, -1, gx, gv, mg);  // y1
  CHECK(gx(1, 0) == Approx(-e).epsilon(1e-12));
  CHECK(gv(1, 0) == Approx(-e * h).epsilon(1e-12));
  CHECK(mg.restitution[0] == Approx(-(y0 + vy * h - c)).epsilon(1e-10));
  grad_of(0, -1, gx, gv, mg);  // x1
  CHECK(gx(0, 0) == Approx(1.0).epsilon(1e-14));
  CHECK(gv(0, 0) == Approx(h).epsilon(1e-14));
  MaterialGrad mv;
  grad_of(-1, 1, gx, gv, mv);  // vy1
  CHECK(gv(1, 0) == Approx(-e).epsilon(1e-12));
  CHECK(gx(1, 0) == Approx(0.0).margin(1e-12));
  CHECK(mv.restitution[0] == Approx(-vy).epsilon(1e-12));
  // The same impulse with its time held fixed (an in-band impulse: d tau = 0, the unsplit
  // step): y1 = y0 + vy tau - e vy (h - tau) moves with y0 one for one, dy1/dy0 = +1, the
  // wrong sign against the runs' -e.
  DriftTape unsplit = o.tape;
  unsplit.impacts[0].kind = ImpactKind::kInBand;
  unsplit.impacts[0].phi = unsplit.impacts[0].offset;  // on the offset: no push back
  Eigen::Matrix2Xd ux = Eigen::Matrix2Xd::Zero(2, 1), uv = ux;
  ux(1, 0) = 1.0;
  MaterialGrad mu;
  drift_adjoint(unsplit, ux, uv, nullptr, mu);
  CHECK(ux(1, 0) == Approx(1.0).epsilon(1e-9));
}

TEST_CASE("drift adjoint: curved obstacle with friction and kick, central differences",
          "[gradients][drift]") {
  Scenario sc;
  RefObstacle disc;
  disc.type = RefObstacle::kCircle;
  disc.a = Vec2(0.0, 0.0);
  disc.radius = 0.3;
  disc.e = 0.7;
  disc.mu = 0.2;
  disc.kick = 0.5;
  sc.obs = {disc};
  sc.h = 0.03;
  sc.discs.x = {Vec2(-0.25, 0.33)};
  sc.discs.v = {Vec2(6.0, -7.0)};
  sc.discs.r = {0.02};
  sc.discs.w = {1.0};
  check_against_fd(sc, 1e-6, 1);
}

TEST_CASE("drift adjoint: sticking friction, central differences", "[gradients][drift]") {
  Scenario sc;
  RefObstacle floor;
  floor.e = 0.3;
  floor.mu = 2.0;  // mu jn > |vt|: the tangential velocity is removed
  sc.obs = {floor};
  sc.discs.x = {Vec2(0.0, 0.04)};
  sc.discs.v = {Vec2(1.0, -6.0)};
  sc.discs.r = {0.01};
  sc.discs.w = {1.0};
  check_against_fd(sc, 1e-6, 1);
}

TEST_CASE("drift adjoint: two impacts in one drift (a corner), central differences",
          "[gradients][drift]") {
  Scenario sc;
  RefObstacle floor, wall;
  floor.e = 0.8;
  wall.a = Vec2(0.1, 0.0);
  wall.n0 = Vec2(-1.0, 0.0);
  wall.e = 0.5;
  sc.obs = {floor, wall};
  sc.discs.x = {Vec2(0.05, 0.05)};
  sc.discs.v = {Vec2(7.0, -6.0)};
  sc.discs.r = {0.01};
  sc.discs.w = {1.0};
  check_against_fd(sc, 1e-6, 2);
}

// Moving obstacles: the impulse uses the obstacle's velocity at the contact point, the
// normal rotates with it (n_t) and, on a curved one, turns with the contact point (H).
TEST_CASE("drift adjoint: rotating flipper-like obstacles, central differences",
          "[gradients][drift]") {
  Scenario plane;
  RefObstacle bar;
  bar.a = Vec2(0.0, 0.0);
  bar.n0 = Vec2(0.0, 1.0);
  bar.pivot = Vec2(-0.3, 0.0);
  bar.omega = 8.0;
  bar.e = 0.9;
  plane.obs = {bar};
  plane.h = 0.03;
  plane.discs.x = {Vec2(0.1, 0.06)};
  plane.discs.v = {Vec2(-1.0, -5.0)};
  plane.discs.r = {0.01};
  plane.discs.w = {1.0};
  check_against_fd(plane, 1e-6, 1);

  Scenario round;
  RefObstacle bumper;
  bumper.type = RefObstacle::kCircle;
  bumper.a = Vec2(0.2, 0.0);
  bumper.radius = 0.05;
  bumper.pivot = Vec2(0.0, 0.0);
  bumper.omega = -10.0;
  bumper.e = 0.75;
  bumper.mu = 0.1;
  round.obs = {bumper};
  round.h = 0.03;
  round.discs.x = {Vec2(0.22, 0.12)};
  round.discs.v = {Vec2(-0.5, -6.0)};
  round.discs.r = {0.01};
  round.discs.w = {1.0};
  check_against_fd(round, 1e-6, 1);
}

// Two equal discs head on, elastic: the velocities swap at the time of impact, so
// x_B(h) = x_A(0) + 2r + v_A h and v_B(h) = v_A(0): d x_B / d x_A(0) = 1, d x_B / d x_B(0) = 0,
// d v_B / d v_A(0) = 1, d v_B / d v_B(0) = 0 (Nimble's example, whose answer is (1, 0, 1, 0)).
TEST_CASE("drift adjoint: two equal discs head on, closed form (1, 0, 1, 0)",
          "[gradients][drift][pairs]") {
  Scenario sc;
  sc.discs.x = {Vec2(0.0, 0.0), Vec2(0.1, 0.0)};
  sc.discs.v = {Vec2(10.0, 0.0), Vec2(0.0, 0.0)};
  sc.discs.r = {0.02, 0.02};
  sc.discs.w = {1.0, 1.0};
  sc.discs.e = 1.0;
  const Out o = run(sc);
  REQUIRE(o.tape.pairs.size() == 1);
  CHECK(o.x(0, 1) == Approx(0.0 + 0.04 + 10.0 * sc.h).epsilon(1e-12));
  Eigen::Matrix2Xd gx = Eigen::Matrix2Xd::Zero(2, 2), gv = gx;
  gx(0, 1) = 1.0;  // x_B(h)
  MaterialGrad mg;
  drift_adjoint(o.tape, gx, gv, nullptr, mg);
  CHECK(gx(0, 0) == Approx(1.0).epsilon(1e-12));
  CHECK(gx(0, 1) == Approx(0.0).margin(1e-12));
  gx.setZero();
  gv.setZero();
  gv(0, 1) = 1.0;  // v_B(h)
  drift_adjoint(o.tape, gx, gv, nullptr, mg);
  CHECK(gv(0, 0) == Approx(1.0).epsilon(1e-12));
  CHECK(gv(0, 1) == Approx(0.0).margin(1e-12));
}

TEST_CASE("drift adjoint: pair contacts and obstacles in one drift, central differences",
          "[gradients][drift][pairs]") {
  Scenario sc;
  RefObstacle floor;
  floor.e = 0.7;
  sc.obs = {floor};
  sc.discs.x = {Vec2(0.0, 0.1), Vec2(0.09, 0.11), Vec2(0.2, 0.3)};
  sc.discs.v = {Vec2(8.0, -3.0), Vec2(-2.0, -3.0), Vec2(0.5, 0.2)};
  sc.discs.r = {0.02, 0.025, 0.02};
  sc.discs.w = {1.0, 0.5, 2.0};
  sc.discs.e = 0.8;
  sc.h = 0.03;
  check_against_fd(sc, 1e-6, 3);
}

TEST_CASE("drift adjoint: pinned particles stay; a pinned disc is an obstacle to others",
          "[gradients][drift][pairs]") {
  Scenario sc;
  sc.discs.x = {Vec2(0.0, 0.0), Vec2(0.08, 0.01)};
  sc.discs.v = {Vec2(9.0, 0.5), Vec2(0.0, 0.0)};
  sc.discs.r = {0.02, 0.03};
  sc.discs.w = {1.0, 0.0};
  sc.discs.e = 0.9;
  check_against_fd(sc, 1e-6, 1);
  const Out o = run(sc);
  Eigen::Matrix2Xd gx = Eigen::Matrix2Xd::Zero(2, 2), gv = gx;
  gv(1, 1) = 1.0;
  MaterialGrad mg;
  drift_adjoint(o.tape, gx, gv, nullptr, mg);
  CHECK(gv(1, 1) == 1.0);  // the pinned particle's velocity passes through
}

TEST_CASE("drift adjoint: grazing and resting impacts are found", "[gradients][drift]") {
  DriftTape t;
  t.t0 = 1.0;
  Impact graze;
  graze.v_before = Vec2(3.0, -1e-9);
  graze.n = Vec2(0.0, 1.0);
  Impact rest = graze;
  rest.v_before = Vec2(0.0, -0.01);
  rest.resting = true;
  rest.tau = 0.5;
  t.impacts = {graze, rest};
  std::vector<Finding> f;
  assess_impacts(t, f);
  REQUIRE(f.size() == 2);
  CHECK(f[0].kind == Finding::Kind::kGrazing);
  CHECK(f[1].kind == Finding::Kind::kResting);
  CHECK(f[1].t == 1.5);
}
