// The integrators' adjoint steps over several steps of a small spring system, against
// central differences of the same steps written out here (the reference), and velocity
// Verlet's impact correction through a bounce.
#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>
#include <vector>

#include "gradients/step_adjoint.hpp"
#include "reference_drift.hpp"

using namespace pinsim;
using namespace pinsim::grad;

namespace {

/// Damped springs f_i = -(ks (l - L) + kd ldot) n (n = (x_i - x_j) / l, ldot = (v_i - v_j).n),
/// f_j = -f_i, and gravity m g; parameters theta = (ks, kd, g_x, g_y). Jacobians in closed form:
///   d f_i / d x_i = -[ks n n^T + (s / l)(I - n n^T) + kd n (v_ij^T (I - n n^T) / l)],
///   s = ks (l - L) + kd ldot,  d f_i / d v_i = -kd n n^T.
struct Springs : ForceModel {
  struct Spring {
    Eigen::Index i, j;
    double rest;
  };
  std::vector<Spring> springs;
  double ks = 50.0, kd = 0.3;
  /// Declared velocity-dependent (as a plugin's capability flag: fixed, whatever kd is).
  bool dissipative = true;
  Eigen::Vector2d g{0.0, -9.81};

  void force(const State& s, Eigen::Matrix2Xd& f) override {
    f.setZero(2, s.x.cols());
    for (Eigen::Index i = 0; i < s.x.cols(); ++i)
      if (s.inv_mass[i] > 0.0) f.col(i) += g / s.inv_mass[i];
    for (const Spring& sp : springs) {
      const Eigen::Vector2d d = s.x.col(sp.i) - s.x.col(sp.j);
      const double l = d.norm();
      const Eigen::Vector2d n = d / l;
      const double ldot = (s.v.col(sp.i) - s.v.col(sp.j)).dot(n);
      const Eigen::Vector2d fi = -(ks * (l - sp.rest) + kd * ldot) * n;
      f.col(sp.i) += fi;
      f.col(sp.j) -= fi;
    }
  }
  void blocks(const State& s, const Spring& sp, Mat2& kx, Mat2& kv) const {
    const Eigen::Vector2d d = s.x.col(sp.i) - s.x.col(sp.j);
    const double l = d.norm();
    const Eigen::Vector2d n = d / l;
    const Eigen::Vector2d vij = s.v.col(sp.i) - s.v.col(sp.j);
    const double ldot = vij.dot(n);
    const Mat2 p = Mat2::Identity() - n * n.transpose();
    const double sc = ks * (l - sp.rest) + kd * ldot;
    kx = -(ks * n * n.transpose() + (sc / l) * p + kd * n * (p * vij / l).transpose());
    kv = -kd * n * n.transpose();
  }
  void vjp(const State& s, const Eigen::Matrix2Xd& w, Eigen::Matrix2Xd& gx,
           Eigen::Matrix2Xd& gv) override {
    for (const Spring& sp : springs) {
      Mat2 kx, kv;
      blocks(s, sp, kx, kv);
      // rows (f_i, f_j) = (+, -) blocks; columns (x_i, x_j) = (+, -)
      const Eigen::Vector2d wd = w.col(sp.i) - w.col(sp.j);
      gx.col(sp.i) += kx.transpose() * wd;
      gx.col(sp.j) -= kx.transpose() * wd;
      gv.col(sp.i) += kv.transpose() * wd;
      gv.col(sp.j) -= kv.transpose() * wd;
    }
  }
  void param_vjp(const State& s, const Eigen::Matrix2Xd& w, Eigen::VectorXd& gp) override {
    for (const Spring& sp : springs) {
      const Eigen::Vector2d d = s.x.col(sp.i) - s.x.col(sp.j);
      const double l = d.norm();
      const Eigen::Vector2d n = d / l;
      const double ldot = (s.v.col(sp.i) - s.v.col(sp.j)).dot(n);
      const double wn = (w.col(sp.i) - w.col(sp.j)).dot(n);
      gp[0] += -(l - sp.rest) * wn;
      gp[1] += -ldot * wn;
    }
    for (Eigen::Index i = 0; i < s.x.cols(); ++i)
      if (s.inv_mass[i] > 0.0) gp.segment<2>(2) += w.col(i) / s.inv_mass[i];
  }
  void jacobians(const State& s, Eigen::SparseMatrix<double>& K, Eigen::SparseMatrix<double>& D) {
    const Eigen::Index n = 2 * s.x.cols();
    std::vector<Eigen::Triplet<double>> tx, tv;
    for (const Spring& sp : springs) {
      Mat2 kx, kv;
      blocks(s, sp, kx, kv);
      for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b)
          for (int r = 0; r < 2; ++r)
            for (int c = 0; c < 2; ++c) {
              const double sign = (a == b) ? 1.0 : -1.0;
              const Eigen::Index pa = a == 0 ? sp.i : sp.j, pb = b == 0 ? sp.i : sp.j;
              tx.emplace_back(2 * pa + r, 2 * pb + c, sign * kx(r, c));
              tv.emplace_back(2 * pa + r, 2 * pb + c, sign * kv(r, c));
            }
    }
    K.resize(n, n);
    D.resize(n, n);
    K.setFromTriplets(tx.begin(), tx.end());
    D.setFromTriplets(tv.begin(), tv.end());
  }
  bool velocity_dependent() const override { return dissipative; }
};

/// A chain of 4 particles, the first pinned, with a diagonal spring: rest lengths off the
/// initial ones so the springs start stretched.
struct System {
  Springs f;
  State s;
  System() {
    s.t = 0.0;
    s.x.resize(2, 4);
    s.x << 0.0, 0.3, 0.62, 0.9, 0.0, -0.05, 0.02, -0.1;
    s.v.resize(2, 4);
    s.v << 0.0, 0.4, -0.3, 0.2, 0.0, 0.1, 0.5, -0.2;
    s.inv_mass.resize(4);
    s.inv_mass << 0.0, 2.0, 1.0, 4.0;
    s.radius = Eigen::VectorXd::Constant(4, 0.01);
    f.springs = {{0, 1, 0.25}, {1, 2, 0.3}, {2, 3, 0.35}, {0, 2, 0.5}};
  }
};

Eigen::Matrix2Xd free_drift(const State& s, const Eigen::Matrix2Xd& v, double h) {
  Eigen::Matrix2Xd x = s.x;
  for (Eigen::Index i = 0; i < x.cols(); ++i)
    if (s.inv_mass[i] > 0.0) x.col(i) += h * v.col(i);
  return x;
}

DriftTape free_tape(const State& s, const Eigen::Matrix2Xd& v, double h) {
  DriftTape d;
  d.t0 = s.t;
  d.h = h;
  d.x_in = s.x;
  d.v_in = v;
  d.inv_mass = s.inv_mass;
  return d;
}

Eigen::Matrix2Xd kicked(const State& s, const Eigen::Matrix2Xd& v, const Eigen::Matrix2Xd& f,
                        double c) {
  Eigen::Matrix2Xd out = v;
  for (Eigen::Index i = 0; i < v.cols(); ++i) out.col(i) += c * s.inv_mass[i] * f.col(i);
  return out;
}

/// The dense matrix a as a BlockSystem with every 2x2 block in its pattern.
BlockSystem dense_blocks(const Eigen::MatrixXd& a) {
  BlockSystem out;
  const int64_t np = a.rows() / 2;
  out.a.first.assign(static_cast<std::size_t>(np) + 1, 0);
  for (int64_t i = 0; i < np; ++i) {
    out.a.first[static_cast<std::size_t>(i) + 1] = (i + 1) * np;
    for (int64_t j = 0; j < np; ++j) {
      out.a.col.push_back(static_cast<int32_t>(j));
      for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 2; ++c) out.a.value.push_back(a(2 * i + r, 2 * j + c));
    }
  }
  out.index();
  return out;
}

/// One reference step of `scheme` on free particles; fills the tape (implicit Euler: its
/// A^T too, as the replay of a run hands it to the adjoint step).
void ref_step(Scheme scheme, Springs& f, State& s, double h, StepTape* tape) {
  Eigen::Matrix2Xd f0;
  f.force(s, f0);
  if (tape) tape->start = s;
  if (scheme == Scheme::kSymplecticEuler) {
    const Eigen::Matrix2Xd v1 = kicked(s, s.v, f0, h);
    if (tape) tape->drift = free_tape(s, v1, h);
    s.x = free_drift(s, v1, h);
    s.v = v1;
  } else if (scheme == Scheme::kVelocityVerlet) {
    const Eigen::Matrix2Xd vh = kicked(s, s.v, f0, 0.5 * h);
    if (tape) tape->drift = free_tape(s, vh, h);
    State s1 = s;
    s1.x = free_drift(s, vh, h);
    s1.v = vh;
    Eigen::Matrix2Xd f1;
    f.force(s1, f1);
    Eigen::Matrix2Xd vp = vh;
    if (f.velocity_dependent()) {
      State sp = s1;
      sp.v = kicked(s1, vh, f1, 0.5 * h);
      vp = sp.v;
      f.force(sp, f1);
    }
    if (tape) {
      tape->x1 = s1.x;
      tape->vc = vh;
      tape->vp = vp;
      tape->predicted = f.velocity_dependent();
    }
    s.x = s1.x;
    s.v = kicked(s1, vh, f1, 0.5 * h);
  } else {
    // (M - h D - h^2 K) dv = h (f + h K v0), dense, pinned rows and columns the identity
    Eigen::SparseMatrix<double> K, D;
    f.jacobians(s, K, D);
    const Eigen::Index n = 2 * s.x.cols();
    Eigen::MatrixXd a = -h * Eigen::MatrixXd(D) - h * h * Eigen::MatrixXd(K);
    const Eigen::Map<const Eigen::VectorXd> v0(s.v.data(), n), fv(f0.data(), n);
    Eigen::VectorXd b = h * (fv + h * (Eigen::MatrixXd(K) * v0));
    for (Eigen::Index i = 0; i < n; ++i) {
      const double w = s.inv_mass[i / 2];
      if (w > 0.0) {
        a(i, i) += 1.0 / w;
        continue;
      }
      a.row(i).setZero();
      a.col(i).setZero();
      a(i, i) = 1.0;
      b[i] = 0.0;
    }
    const Eigen::VectorXd dv = a.partialPivLu().solve(b);
    if (tape) {
      tape->system = dense_blocks(a.transpose());
      tape->has_system = true;
      tape->symmetric = (a - a.transpose()).norm() <= 1e-14 * a.norm();
    }
    Eigen::Matrix2Xd v1 = s.v + Eigen::Map<const Eigen::Matrix2Xd>(dv.data(), 2, s.x.cols());
    if (tape) tape->drift = free_tape(s, v1, h);
    s.x = free_drift(s, v1, h);
    s.v = v1;
  }
  s.t += h;
}

/// a.x_N + b.v_N after `steps` steps.
double run_functional(Scheme scheme, System sys, int steps, double h, const Eigen::Matrix2Xd& a,
                      const Eigen::Matrix2Xd& b) {
  for (int k = 0; k < steps; ++k) ref_step(scheme, sys.f, sys.s, h, nullptr);
  return (a.array() * sys.s.x.array()).sum() + (b.array() * sys.s.v.array()).sum();
}

void check_scheme(Scheme scheme, double kd, bool dissipative = true) {
  System sys;
  sys.f.kd = kd;
  sys.f.dissipative = dissipative;
  const int steps = 40;
  const double h = 0.01;
  Eigen::Matrix2Xd a(2, 4), b(2, 4);
  a << 0.0, 0.5, -0.3, 1.0, 0.0, 0.2, 0.7, -0.4;
  b << 0.0, 0.1, 0.05, -0.2, 0.0, 0.3, -0.1, 0.15;
  // forward with tapes, then the adjoint back
  System fw = sys;
  std::vector<StepTape> tapes(steps);
  for (int k = 0; k < steps; ++k)
    ref_step(scheme, fw.f, fw.s, h, &tapes[static_cast<std::size_t>(k)]);
  // implicit Euler: both solver paths are exercised, conjugate gradients for the symmetric
  // A of kd = 0, BiCGSTAB for the turning damped springs (the tapes' flag chooses)
  if (scheme == Scheme::kImplicitEuler) CHECK(tapes[0].symmetric == (kd == 0.0));
  Adjoint adj;
  adj.reset(4, 4);
  adj.gx = a;
  adj.gv = b;
  AdjointStats st;
  for (int k = steps; k-- > 0;)
    adjoint_step(scheme, fw.f, tapes[static_cast<std::size_t>(k)], h, adj, st);
  // central differences of the whole run
  const double eps = 1e-6;
  auto fd = [&](auto&& perturb) {
    System p = sys, m = sys;
    perturb(p, eps);
    perturb(m, -eps);
    return (run_functional(scheme, p, steps, h, a, b) - run_functional(scheme, m, steps, h, a, b)) /
           (2.0 * eps);
  };
  std::vector<double> got, want;
  for (Eigen::Index i = 0; i < 4; ++i)
    for (int c = 0; c < 2; ++c) {
      got.push_back(adj.gx(c, i));
      want.push_back(fd([&](System& s, double d) { s.s.x(c, i) += d; }));
      got.push_back(adj.gv(c, i));
      want.push_back(fd([&](System& s, double d) { s.s.v(c, i) += d; }));
    }
  got.push_back(adj.gp[0]);
  want.push_back(fd([&](System& s, double d) { s.f.ks += d; }));
  got.push_back(adj.gp[1]);
  want.push_back(fd([&](System& s, double d) { s.f.kd += d; }));
  got.push_back(adj.gp[3]);
  want.push_back(fd([&](System& s, double d) { s.f.g.y() += d; }));
  double scale = 0.0;
  for (double w : want) scale = std::max(scale, std::abs(w));
  for (std::size_t k = 0; k < got.size(); ++k) {
    INFO("input " << k << ": adjoint " << got[k] << ", central difference " << want[k]);
    CHECK(std::abs(got[k] - want[k]) <= 1e-7 * scale);
  }
  if (scheme == Scheme::kImplicitEuler) {
    CHECK(st.solves == static_cast<uint64_t>(steps));
    CHECK(st.lu_fallbacks == 0);  // the block solvers, not their LU fallback, gave mu
    CHECK(st.solve_iterations >= static_cast<uint64_t>(steps));
    CHECK(st.worst_residual <= 1e-11);
  }
}

}  // namespace

TEST_CASE("adjoint step: symplectic Euler on damped springs, central differences",
          "[gradients][steps]") {
  check_scheme(Scheme::kSymplecticEuler, 0.3);
}

TEST_CASE("adjoint step: velocity Verlet with and without its predictor", "[gradients][steps]") {
  check_scheme(Scheme::kVelocityVerlet, 0.0, false);
  check_scheme(Scheme::kVelocityVerlet, 0.3, true);
}

TEST_CASE("adjoint step: implicit Euler, the transposed solve and its second-order terms",
          "[gradients][steps]") {
  check_scheme(Scheme::kImplicitEuler, 0.0);
  check_scheme(Scheme::kImplicitEuler, 0.3);
}

// A projectile under gravity, symplectic Euler: x(T) = x0 + vx0 T, so d x(T) / d vx0 = T
// exactly, for any step (the kicks do not depend on the state).
TEST_CASE("adjoint step: projectile, d x(T) / d v0 = T", "[gradients][steps]") {
  Springs f;
  State s;
  s.x = Eigen::Matrix2Xd::Zero(2, 1);
  s.v.resize(2, 1);
  s.v << 5.0, 5.0;
  s.inv_mass = Eigen::VectorXd::Ones(1);
  s.radius = Eigen::VectorXd::Constant(1, 0.05);
  const double h = 0.001;
  const int steps = 1000;
  std::vector<StepTape> tapes(steps);
  for (int k = 0; k < steps; ++k)
    ref_step(Scheme::kSymplecticEuler, f, s, h, &tapes[static_cast<std::size_t>(k)]);
  Adjoint adj;
  adj.reset(1, 4);
  adj.gx(0, 0) = 1.0;
  AdjointStats st;
  for (int k = steps; k-- > 0;)
    adjoint_step(Scheme::kSymplecticEuler, f, tapes[static_cast<std::size_t>(k)], h, adj, st);
  CHECK(adj.gv(0, 0) == Approx(steps * h).epsilon(1e-12));
  CHECK(adj.gx(0, 0) == 1.0);
  CHECK(adj.gv(1, 0) == 0.0);
}

// Velocity Verlet bouncing on a floor under gravity, through correct_impacts' change of the
// impulse: the impacts' times, normals and restitution reach the adjoint as seeds.
TEST_CASE("adjoint step: velocity Verlet's impact correction, central differences",
          "[gradients][steps][drift]") {
  using testing::RefObstacle;
  std::vector<RefObstacle> obs(1);
  obs[0].e = 0.7;
  Springs f;
  f.g = Eigen::Vector2d(0.0, -9.81);
  const double h = 0.01, offset = 0.01 + 1e-5;
  const int steps = 30;
  auto run = [&](const Eigen::Vector2d& x0, const Eigen::Vector2d& v0, double e,
                 std::vector<StepTape>* tapes) {
    std::vector<RefObstacle> o = obs;
    o[0].e = e;
    State s;
    s.x = x0;
    s.v = v0;
    s.inv_mass = Eigen::VectorXd::Ones(1);
    s.radius = Eigen::VectorXd::Constant(1, 0.01);
    for (int k = 0; k < steps; ++k) {
      StepTape t;
      t.start = s;
      Eigen::Matrix2Xd f0;
      f.force(s, f0);
      const Eigen::Matrix2Xd vh = kicked(s, s.v, f0, 0.5 * h);
      t.drift = free_tape(s, vh, h);
      Vec2 x = s.x.col(0), v = vh.col(0);
      testing::ref_drift(o, offset, s.t, h, x, v, 0, &t.drift.impacts);
      // correct_impacts: v -= (1 + e)(tau - h/2)(a0.n) n per impact
      for (const Impact& m : t.drift.impacts) {
        const double vb = (m.v_before - m.u).dot(m.n), va = (m.v_after - m.u).dot(m.n);
        const double c = std::clamp((va - vb) / -vb, 1.0, 2.0);
        v -= c * (m.tau - 0.5 * h) * f0.col(0).dot(m.n) * m.n;
      }
      State s1 = s;
      s1.x.col(0) = x;
      s1.v.col(0) = v;
      Eigen::Matrix2Xd f1;
      f.force(s1, f1);
      t.x1 = s1.x;
      t.vc = s1.v;
      s = s1;
      s.v = kicked(s1, s1.v, f1, 0.5 * h);
      s.t += h;
      if (tapes) tapes->push_back(t);
    }
    return s;
  };
  const Eigen::Vector2d x0(0.0, 0.3), v0(0.4, -1.5);
  std::vector<StepTape> tapes;
  const State end = run(x0, v0, 0.7, &tapes);
  std::size_t impacts = 0;
  for (const auto& t : tapes) impacts += t.drift.impacts.size();
  REQUIRE(impacts >= 1);
  Adjoint adj;
  adj.reset(1, 4);
  adj.gx << 0.3, 1.0;
  adj.gv << -0.2, 0.5;
  AdjointStats st;
  for (std::size_t k = tapes.size(); k-- > 0;)
    adjoint_step(Scheme::kVelocityVerlet, f, tapes[k], h, adj, st);
  auto value = [&](const State& s) {
    return 0.3 * s.x(0, 0) + s.x(1, 0) - 0.2 * s.v(0, 0) + 0.5 * s.v(1, 0);
  };
  (void)end;
  const double eps = 1e-7;
  auto fd = [&](int which) {
    Eigen::Vector2d xp = x0, xm = x0, vp = v0, vm = v0;
    double ep = 0.7, em = 0.7;
    if (which < 2) {
      xp[which] += eps;
      xm[which] -= eps;
    } else if (which < 4) {
      vp[which - 2] += eps;
      vm[which - 2] -= eps;
    } else {
      ep += eps;
      em -= eps;
    }
    return (value(run(xp, vp, ep, nullptr)) - value(run(xm, vm, em, nullptr))) / (2.0 * eps);
  };
  CHECK(adj.gx(0, 0) == Approx(fd(0)).epsilon(1e-6));
  CHECK(adj.gx(1, 0) == Approx(fd(1)).epsilon(1e-6));
  CHECK(adj.gv(0, 0) == Approx(fd(2)).epsilon(1e-6));
  CHECK(adj.gv(1, 0) == Approx(fd(3)).epsilon(1e-6));
  CHECK(MaterialGrad::at(adj.material.restitution, 0) == Approx(fd(4)).epsilon(1e-6));
}
