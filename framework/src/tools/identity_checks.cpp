// check-plugin's checks of exact identities: an internal force's momentum, angular momentum
// and invariance under rigid motions, and a damping force's dissipation.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <string>

#include "core/format.hpp"
#include "tools/plugin_checker.hpp"

namespace pinsim::plugin_check {

namespace {

bool is_internal(const pinsim_plugin* t, const CheckOptions& o) {
  return (t->capabilities & PINSIM_CAP_INTERNAL) || o.assume_internal;
}

double cross(const Vector2d& a, const Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

}  // namespace

CheckResult Checker::momentum_check(bool angular) {
  CheckResult r{angular ? "angular_momentum" : "momentum",
                angular ? "internal force: sum of x cross f = 0" : "internal force: sum f = 0",
                CheckStatus::Pass,
                0.0,
                opt_.identity_tolerance,
                ""};
  if (!is_internal(t_, opt_)) {
    r.status = CheckStatus::Skip;
    r.detail = "not an internal force (PINSIM_CAP_INTERNAL not declared)";
    return r;
  }
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample s = random_state();
    auto inst = make(init);
    const VectorXd fv = inst->force(s);
    const Eigen::Map<const Matrix2Xd> f(fv.data(), 2, fv.size() / 2);
    double err = 0.0, scale = 1e-300;
    if (!angular) {
      err = f.rowwise().sum().norm();
      scale += f.colwise().norm().sum();
    } else {
      double tq = 0.0;
      for (Eigen::Index i = 0; i < f.cols(); ++i) {
        tq += cross(s.x.col(i), f.col(i));
        scale += s.x.col(i).norm() * f.col(i).norm();
      }
      err = std::abs(tq);
    }
    const double e = std::isfinite(err) ? err / scale : std::numeric_limits<double>::infinity();
    keep_worst(r, e, e <= r.tolerance,
               "state " + std::to_string(trial) + ": |" + (angular ? "sum x*f" : "sum f") +
                   "| = " + num(err, 3) + " against a scale of " + num(scale, 3));
  }
  return r;
}

CheckResult Checker::invariance_check() {
  CheckResult r{
      "rigid_invariance",      "energy unchanged and forces rotated under random rigid motions",
      CheckStatus::Pass,       0.0,
      opt_.identity_tolerance, ""};
  if (!is_internal(t_, opt_)) {
    r.status = CheckStatus::Skip;
    r.detail = "not an internal force (PINSIM_CAP_INTERNAL not declared)";
    return r;
  }
  const bool has_e = (t_->capabilities & PINSIM_CAP_ENERGY) != 0;
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample s = random_state();
    auto inst = make(init);
    const double th = uni(-M_PI, M_PI);
    Eigen::Matrix2d q;
    q << std::cos(th), -std::sin(th), std::sin(th), std::cos(th);
    const Vector2d tr(uni(-3, 3), uni(-3, 3));
    Sample m = s;
    m.x = (q * s.x).colwise() + tr;
    m.v = q * s.v;
    const VectorXd f0 = inst->force(s), f1 = inst->force(m);
    const Eigen::Map<const Matrix2Xd> a(f0.data(), 2, f0.size() / 2);
    Matrix2Xd rot = q * a;
    const Eigen::Map<const VectorXd> rotv(rot.data(), rot.size());
    const double scale = f0.cwiseAbs().maxCoeff() + 1e-300;
    double e = (f1 - rotv).cwiseAbs().maxCoeff() / scale;
    std::string what = "forces differ from the rotated forces by " + num(e, 3) + " relative";
    if (has_e) {
      const double e0 = inst->energy(s), e1 = inst->energy(m);
      // Scale: |E| plus the work the forces would do over the configuration's extent.
      const double escale = std::abs(e0) + f0.cwiseAbs().sum() * 2.0 + 1e-300;
      const double de = std::abs(e1 - e0) / escale;
      if (!(de <= e)) what = "energy " + num(e0, 3) + " became " + num(e1, 3);
      e = std::max(e, de);
      if (!std::isfinite(de)) e = std::numeric_limits<double>::infinity();
    }
    if (!std::isfinite(e)) e = std::numeric_limits<double>::infinity();
    keep_worst(r, e, e <= r.tolerance,
               "state " + std::to_string(trial) + ", rotation " + num(th, 3) + " rad: " + what);
  }
  return r;
}

CheckResult Checker::dissipation_check() {
  CheckResult r{"dissipation",
                "damping never adds energy: (f(x,v) - f(x,0))·v <= 0 and df/dv negative "
                "semidefinite",
                CheckStatus::Pass,
                0.0,
                opt_.identity_tolerance,
                ""};
  if (!(t_->capabilities & PINSIM_CAP_DISSIPATIVE)) {
    r.status = CheckStatus::Skip;
    r.detail = "no damping (PINSIM_CAP_DISSIPATIVE not declared)";
    return r;
  }
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample s = random_state();
    Sample still = s;
    still.v.setZero();
    auto inst = make(init);
    const VectorXd fd = inst->force(s) - inst->force(still);
    const Eigen::Map<const VectorXd> v(s.v.data(), s.v.size());
    const double p = fd.dot(v);
    const double scale = fd.norm() * v.norm() + 1e-300;
    double e = std::max(0.0, p) / scale;
    std::string what = "damping power " + num(p, 3);
    if (inst->has(PINSIM_CAP_DFDV) && t_->force.add_jacobians != nullptr) {
      const MatrixXd k = inst->jacobian(s, 1);
      const MatrixXd sym = 0.5 * (k + k.transpose());
      const double kmax = sym.cwiseAbs().maxCoeff();
      if (kmax > 0 && std::isfinite(kmax)) {
        const double lmax = Eigen::SelfAdjointEigenSolver<MatrixXd>(sym).eigenvalues().maxCoeff();
        const double el = std::max(0.0, lmax) / kmax;
        if (el > e) what = "df/dv has a positive eigenvalue " + num(lmax, 3);
        e = std::max(e, el);
      } else if (!std::isfinite(kmax)) {
        e = std::numeric_limits<double>::infinity();
      }
    }
    if (!std::isfinite(p)) e = std::numeric_limits<double>::infinity();
    keep_worst(r, e, e <= r.tolerance, "state " + std::to_string(trial) + ": " + what);
  }
  return r;
}

}  // namespace pinsim::plugin_check
