// The adjoint step of linearized backward Euler: the transposed solve of its own system.
#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "gradients/step_adjoint.hpp"

namespace pinsim::grad {
namespace {

using Sparse = Eigen::SparseMatrix<double>;

Eigen::Map<const Eigen::VectorXd> flat(const Eigen::Matrix2Xd& m) { return {m.data(), m.size()}; }

/// Solves A^T mu = rhs with A^T as the step's replay assembled it (`at`), by the forward's own
/// solvers (core/block_krylov.hpp): conjugate gradients when A is symmetric, BiCGSTAB
/// otherwise, Jacobi-preconditioned to a relative residual of 1e-12, started from the last
/// adjoint step's mu when that beats 0 (the adjoint, like the motion, changes little from
/// step to step); sparse LU if they fail or the true residual |A^T mu - rhs| exceeds 1e-11 of
/// |rhs|. Throws std::runtime_error if that fails too (residual above 1e-10).
const Eigen::VectorXd& transposed_solve(const BlockSystem& at, bool symmetric,
                                        const Eigen::Map<const Eigen::VectorXd>& rhs,
                                        Adjoint::Scratch& sc, AdjointStats& st) {
  ++st.solves;
  const Eigen::Index n = rhs.size();
  sc.rhs = rhs;
  if (sc.mu.size() != n) sc.mu.setZero(n);
  if (sc.r.size() != n) sc.r.resize(n);
  sc.krylov.resize(n / 2);
  double bb = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) bb += sc.rhs[i] * sc.rhs[i];
  if (!(sc.krylov.residual_of(at, sc.rhs, sc.mu, sc.r) < bb)) {
    sc.mu.setZero();
    sc.r = sc.rhs;
  }
  const Eigen::Index max_iterations = std::max<Eigen::Index>(100, 4 * n);
  const BlockKrylov::Solve out =
      symmetric ? sc.krylov.cg(at, bb, sc.mu, sc.r, max_iterations)
                : sc.krylov.bicgstab(at, sc.rhs, bb, sc.mu, sc.r, max_iterations);
  st.solve_iterations += static_cast<uint64_t>(out.iterations);
  // the true residual |A^T mu - rhs| / |rhs| (the iteration's own can drift from it)
  double res = bb > 0.0 ? std::sqrt(sc.krylov.residual_of(at, sc.rhs, sc.mu, sc.r) / bb) : 0.0;
  if (!out.converged || !(res <= 1e-11)) {
    ++st.lu_fallbacks;
    const Sparse a = at.a.to_eigen();
    Eigen::SparseLU<Sparse> lu;
    lu.compute(a);
    if (lu.info() != Eigen::Success)
      throw std::runtime_error("implicit_euler adjoint: the transposed system is singular");
    sc.mu = lu.solve(sc.rhs);
    const double bn = std::sqrt(bb);
    res = (a * sc.mu - sc.rhs).norm() / (bn > 0.0 ? bn : 1.0);
    if (!(res <= 1e-10))
      throw std::runtime_error(
          "implicit_euler adjoint: the transposed solve left relative residual " +
          std::to_string(res));
  }
  st.worst_residual = std::max(st.worst_residual, res);
  return sc.mu;
}

}  // namespace

// Forward (integrator_implicit_euler.cpp):
//   A dv = b,  A = M - h D - h^2 K,  b = h (f + h K v0)  (pinned rows 0),  v' = v0 + dv,
//   then (x1, v1) = drift(x0, v').
// With mu = A^-T (adjoint of dv), the first-order terms are
//   xbar += h K^T mu,  vbar += h D^T mu + h^2 K^T mu,  thetabar += h (df/dtheta)^T mu,
// and the second-order ones, from K and D changing with the state and the parameters in
//   mu^T dA dv and mu^T db:  phi(x, v, theta) = mu^T (h^2 K v' + h D dv),
//   xbar += d phi / dx = d/deps [K(x + eps a, v + eps c)^T mu]  (a = h^2 v', c = h dv),
//   vbar += d phi / dv = d/deps [D(x + eps a, v + eps c)^T mu],
//   thetabar += d phi / dtheta = d/deps [(df/dtheta)(x + eps a, v + eps c)^T mu],
// each a directional derivative of the Jacobian products along one direction, here by
// central differences with eps scaled so the shift is 1e-5 of the state's size (truncation
// O(eps^2), rounding O(1e-16 / 1e-5) relative; zero for forces linear in the state).
void adjoint_implicit_euler(ForceModel& forces, const StepTape& tape, double h, Adjoint& a,
                            AdjointStats& stats) {
  const State& s0 = tape.start;
  const Eigen::Index np = s0.x.cols();
  const Eigen::Matrix2Xd& vmid = tape.drift.v_in;
  const Eigen::Matrix2Xd dv = vmid - s0.v;
  if (!tape.has_system)
    throw std::logic_error("implicit_euler adjoint: the step record has no system");
  drift_adjoint(tape.drift, a.gx, a.gv, nullptr, a.material);
  // v' = v0 + dv: v0 gets a.gv as it is; dv's adjoint on free dofs only
  Eigen::Matrix2Xd lam = a.gv;
  for (Eigen::Index i = 0; i < np; ++i)
    if (!(s0.inv_mass[i] > 0.0)) lam.col(i).setZero();
  // first order: b = h f + h^2 K v0; kx = h K^T mu, dx = h D^T mu
  Eigen::Matrix2Xd mu(2, np), kx = Eigen::Matrix2Xd::Zero(2, np), dx = kx;
  Eigen::Map<Eigen::VectorXd>(mu.data(), mu.size()) =
      transposed_solve(tape.system, tape.symmetric, flat(lam), a.scratch, stats);
  const Eigen::Matrix2Xd hmu = h * mu;
  forces.vjp_with_params(ForceModel::Part::kAll, s0, hmu, kx, dx, a.gp);
  a.gx += kx;
  a.gv += dx + h * kx;
  // second order, along (a, c) = (h^2 v', h dv)
  const Eigen::Matrix2Xd dir_x = h * h * vmid, dir_v = h * dv;
  const double sx = dir_x.cwiseAbs().maxCoeff(), sv = dir_v.cwiseAbs().maxCoeff();
  if (!(sx > 0.0 || sv > 0.0) || mu.isZero(0.0)) return;
  const double xs = 1.0 + s0.x.cwiseAbs().maxCoeff(), vs = 1.0 + s0.v.cwiseAbs().maxCoeff();
  double eps = HUGE_VAL;
  if (sx > 0.0) eps = std::min(eps, 1e-5 * xs / sx);
  if (sv > 0.0) eps = std::min(eps, 1e-5 * vs / sv);
  State sp = s0, sm = s0;
  sp.x += eps * dir_x;
  sp.v += eps * dir_v;
  sm.x -= eps * dir_x;
  sm.v -= eps * dir_v;
  Eigen::Matrix2Xd gxp = Eigen::Matrix2Xd::Zero(2, np), gvp = gxp, gxm = gxp, gvm = gxp;
  forces.vjp(sp, mu, gxp, gvp);
  forces.vjp(sm, mu, gxm, gvm);
  a.gx += (gxp - gxm) / (2.0 * eps);
  a.gv += (gvp - gvm) / (2.0 * eps);
  if (a.gp.size() > 0) forces.param_jacobian_vjp(s0, mu, dir_x, dir_v, eps, a.gp);
}

}  // namespace pinsim::grad
