// check-plugin's finite-difference checks: f = -dE/dx, df/dx and df/dv, and the constraint
// entry against the energy, the force and differences of C.
#include <string>

#include "core/format.hpp"
#include "tools/plugin_checker.hpp"

namespace pinsim::plugin_check {

CheckResult Checker::gradient_check() {
  CheckResult r{"gradient",        "f = -dE/dx by central differences, step halving",
                CheckStatus::Pass, 0.0,
                opt_.fd_tolerance, ""};
  if (!(t_->capabilities & PINSIM_CAP_ENERGY)) {
    r.status = CheckStatus::Skip;
    r.detail = "no energy (PINSIM_CAP_ENERGY not declared)";
    return r;
  }
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    Sample s = random_state(false);  // v = 0: only the conservative part
    auto inst = make(init);
    const VectorXd f = inst->force(s);
    auto fd = [&](double h) {
      VectorXd g(f.size());
      for (Eigen::Index j = 0; j < f.size(); ++j) {
        Sample p = s, m = s;
        p.x.data()[j] += h;
        m.x.data()[j] -= h;
        g[j] = -(inst->energy(p) - inst->energy(m)) / (2 * h);
      }
      return g;
    };
    const VectorXd g1 = fd(kStep), g2 = fd(kStep / 2);
    Eigen::Index at = 0;
    const double e1 = rel(f, g1, nullptr), e2 = rel(f, g2, &at);
    const Eigen::Index j = at / 1000;
    const bool ok = converged(e1, e2);
    keep_worst(r, e2, ok,
               "state " + std::to_string(trial) + ", " + dof_name(j) + ": f = " + num(f[j], 3) +
                   ", -dE/dx = " + num(g2[j], 3) + "; error " + num(e1, 3) + " at h, " +
                   num(e2, 3) + " at h/2" + (ok ? "" : " (does not converge)"));
  }
  return r;
}

CheckResult Checker::jacobian_check(int which) {
  const char* name = which == 0 ? "dfdx" : "dfdv";
  CheckResult r{name,
                which == 0 ? "df/dx against central differences of f, step halving"
                           : "df/dv against central differences of f, step halving",
                CheckStatus::Pass,
                0.0,
                opt_.fd_tolerance,
                ""};
  const uint32_t cap = which == 0 ? PINSIM_CAP_DFDX : PINSIM_CAP_DFDV;
  if (!(t_->capabilities & cap) || t_->force.add_jacobians == nullptr) {
    r.status = CheckStatus::Skip;
    r.detail = std::string("not provided (PINSIM_CAP_") + (which == 0 ? "DFDX" : "DFDV") +
               " not declared)";
    return r;
  }
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample s = random_state();
    auto inst = make(init);
    const MatrixXd k = inst->jacobian(s, which);
    auto fd = [&](double h) {
      MatrixXd g(k.rows(), k.cols());
      for (Eigen::Index j = 0; j < k.cols(); ++j) {
        Sample p = s, m = s;
        (which == 0 ? p.x : p.v).data()[j] += h;
        (which == 0 ? m.x : m.v).data()[j] -= h;
        g.col(j) = (inst->force(p) - inst->force(m)) / (2 * h);
      }
      return g;
    };
    const MatrixXd g1 = fd(kStep), g2 = fd(kStep / 2);
    Eigen::Index at = 0;
    const double e1 = rel(k, g1, nullptr), e2 = rel(k, g2, &at);
    const Eigen::Index row = at / 1000, col = at % 1000;
    const bool ok = converged(e1, e2);
    keep_worst(r, e2, ok,
               "state " + std::to_string(trial) + ", d(" + dof_name(row) + ")/d(" + dof_name(col) +
                   "): analytic " + num(k(row, col), 3) + ", difference " + num(g2(row, col), 3) +
                   "; error " + num(e1, 3) + " at h, " + num(e2, 3) + " at h/2" +
                   (ok ? "" : " (does not converge)"));
  }
  return r;
}

// The constraint entry (which: 0 energy, 1 force, 2 gradient) on random states: E = sum
// ks/2 C^2 up to a constant, f = -sum J^T (ks C + kd J v), dC/dp by central differences.
CheckResult Checker::constraint_check(int which) {
  static const char* const names[] = {"constraint_energy", "constraint_force",
                                      "constraint_gradient"};
  static const char* const whats[] = {
      "constraints: E(x) - E(x0) = sum ks/2 (C(x)^2 - C(x0)^2)",
      "constraints: add_force = -sum J^T (ks C + kd J v)",
      "constraints: dC/dp against central differences of C, step halving"};
  CheckResult r{names[which],
                whats[which],
                CheckStatus::Pass,
                0.0,
                which == 2 ? opt_.fd_tolerance : 1e-8,
                ""};
  if (!(t_->capabilities & PINSIM_CAP_CONSTRAINTS)) {
    r.status = CheckStatus::Skip;
    r.detail = "no constraints (PINSIM_CAP_CONSTRAINTS not declared)";
    return r;
  }
  if (which == 0 && !(t_->capabilities & PINSIM_CAP_ENERGY)) {
    r.status = CheckStatus::Skip;
    r.detail = "no energy to compare with (PINSIM_CAP_ENERGY not declared)";
    return r;
  }
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample a = random_state(), b = random_state();
    auto inst = make(init);
    const ConstraintProbe p = inst->probe(a);
    const Eigen::Map<const VectorXd> xa(a.x.data(), a.x.size()), va(a.v.data(), a.v.size()),
        xb(b.x.data(), b.x.size());
    std::string detail;
    const std::string state = "state " + std::to_string(trial) + ": ";
    if (which == 0) {
      const double e = constraint_energy_error(p, xb, xa, detail);
      keep_worst(r, e, e <= r.tolerance, state + detail);
    } else if (which == 1) {
      const double e = constraint_force_error(p, xa, va, detail);
      keep_worst(r, e, e <= r.tolerance, state + detail);
    } else {
      std::string d1;
      const double e1 = constraint_gradient_error(p, xa, kStep, d1);
      const double e2 = constraint_gradient_error(p, xa, kStep / 2, detail);
      const bool ok = converged(e1, e2);
      keep_worst(r, e2, ok,
                 state + detail + "; error " + num(e1, 3) + " at h, " + num(e2, 3) + " at h/2" +
                     (ok ? "" : " (does not converge)"));
    }
  }
  return r;
}

}  // namespace pinsim::plugin_check
