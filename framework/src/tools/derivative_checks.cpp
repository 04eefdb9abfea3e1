// check-plugin's finite-difference checks: f = -dE/dx, df/dx and df/dv, and the constraint
// entry against the energy, the force and differences of C.
#include <algorithm>
#include <string>

#include "core/format.hpp"
#include "tools/plugin_checker.hpp"

namespace pinsim::plugin_check {

namespace {

/// The step-halving verdict's words: "; error e1 at h, e2 at h/2" and whether it converged.
std::string halving_text(double e1, double e2, bool ok) {
  return "; error " + num(e1, 3) + " at h, " + num(e2, 3) + " at h/2" +
         (ok ? "" : " (does not converge)");
}

}  // namespace

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
                   ", -dE/dx = " + num(g2[j], 3) + halving_text(e1, e2, ok));
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
                   halving_text(e1, e2, ok));
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
      keep_worst(r, e2, ok, state + detail + halving_text(e1, e2, ok));
    }
  }
  return r;
}

// d f / d theta from the plugin (add_dforce_dparam) for every parameter it flags
// PINSIM_PARAM_DIFFERENTIABLE, against differences of add_force over instances created with
// theta moved by h = kStep max(|theta|, 1): central, (f(theta + h) - f(theta - h)) / (2 h),
// or where a bound leaves one side only the one-sided second-order
// (-3 f(theta) + 4 f(theta + h) - f(theta + 2 h)) / (2 h) (h < 0 for the lower side);
// both O(h^2), so step halving applies.
CheckResult Checker::dparam_check() {
  CheckResult r{"dparam",
                "d f / d parameter against differences of f over the parameter, step halving",
                CheckStatus::Pass,
                0.0,
                opt_.fd_tolerance,
                ""};
  if (!(t_->capabilities & PINSIM_CAP_DPARAM) || t_->add_dforce_dparam == nullptr) {
    r.status = CheckStatus::Skip;
    r.detail = "no parameter derivatives (PINSIM_CAP_DPARAM not declared)";
    return r;
  }
  const nlohmann::json values = nlohmann::json::parse(params_);
  // whether theta + d stays inside the parameter's declared bounds
  auto inside = [](const pinsim_param& p, double x) {
    const bool lo = (p.flags & PINSIM_PARAM_MIN_EXCLUSIVE) ? x > p.min : x >= p.min;
    const bool hi = (p.flags & PINSIM_PARAM_MAX_EXCLUSIVE) ? x < p.max : x <= p.max;
    return lo && hi;
  };
  int checked = 0;
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample s = random_state();
    auto inst = make(init);
    for (uint32_t i = 0; i < t_->n_params; ++i) {
      const pinsim_param& p = t_->params[i];
      if (!(p.flags & PINSIM_PARAM_DIFFERENTIABLE)) continue;
      const int comps = p.type == PINSIM_PARAM_VEC2 ? 2 : 1;
      for (int c = 0; c < comps; ++c) {
        const nlohmann::json& v = values.at(p.name);
        const double theta =
            v.is_array() ? v.at(static_cast<std::size_t>(c)).get<double>() : v.get<double>();
        const VectorXd a = inst->dforce_dparam(s, i, static_cast<uint32_t>(c));
        auto force_at = [&](double x) { return make_with(init, p.name, c, x)->force(s); };
        auto fd = [&](double h) -> VectorXd {
          if (inside(p, theta - h) && inside(p, theta + h))
            return (force_at(theta + h) - force_at(theta - h)) / (2 * h);
          const double d = inside(p, theta + 2 * h) ? h : -h;
          return (-3.0 * inst->force(s) + 4.0 * force_at(theta + d) - force_at(theta + 2 * d)) /
                 (2 * d);
        };
        const double h = kStep * std::max(std::abs(theta), 1.0);
        if (!inside(p, theta + 2 * h) && !inside(p, theta - 2 * h)) continue;  // no room
        ++checked;
        const VectorXd g1 = fd(h), g2 = fd(h / 2);
        Eigen::Index at = 0;
        const double e1 = rel(a, g1, nullptr), e2 = rel(a, g2, &at);
        const Eigen::Index j = at / 1000;
        const bool ok = converged(e1, e2);
        const std::string what = std::string(p.name) + (comps == 2 ? (c == 0 ? "[0]" : "[1]") : "");
        keep_worst(r, e2, ok,
                   "state " + std::to_string(trial) + ", d(" + dof_name(j) + ")/d " + what +
                       " at " + what + " = " + num(theta, 6) + ": plugin " + num(a[j], 3) +
                       ", difference " + num(g2[j], 3) + halving_text(e1, e2, ok));
      }
    }
  }
  if (checked == 0) {
    r.status = CheckStatus::Skip;
    r.detail = "every differentiable parameter sits where its bounds leave no room to differ";
  }
  return r;
}

// The plugin's transposed Jacobian products (add_jacobian_products) against its Jacobians'
// entries multiplied out, (df/dx)^T w and (df/dv)^T w for random w: the same numbers up to
// rounding (the entries themselves are checked against differences by dfdx and dfdv).
CheckResult Checker::products_check() {
  CheckResult r{"jacobian_products",
                "(df/dx)^T w and (df/dv)^T w against the Jacobians' entries, random w",
                CheckStatus::Pass,
                0.0,
                opt_.identity_tolerance,
                ""};
  if (!(t_->capabilities & PINSIM_CAP_JACOBIAN_PRODUCTS) || t_->add_jacobian_products == nullptr ||
      t_->force.add_jacobians == nullptr) {
    r.status = CheckStatus::Skip;
    r.detail = "no Jacobian products (PINSIM_CAP_JACOBIAN_PRODUCTS not declared)";
    return r;
  }
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample s = random_state();
    auto inst = make(init);
    const VectorXd w = random_field(s);
    for (int which = 0; which < 2; ++which) {
      if (which == 1 && !(t_->capabilities & PINSIM_CAP_DFDV)) continue;
      const VectorXd want = inst->jacobian(s, which).transpose() * w;
      const VectorXd got = inst->jacobian_product(s, w, which);
      Eigen::Index at = 0;
      const double e = rel(got, want, &at);
      const Eigen::Index j = at / 1000;
      keep_worst(r, e, e <= r.tolerance,
                 "state " + std::to_string(trial) + ", " + (which == 0 ? "(df/dx)" : "(df/dv)") +
                     "^T w at " + dof_name(j) + ": plugin " + num(got[j], 6) + ", entries " +
                     num(want[j], 6) + "; error " + num(e, 3));
    }
  }
  return r;
}

// The plugin's fused products (add_adjoint_products) against its separate entries: gx and
// gv against add_jacobian_products', and gp[j] against w . add_dforce_dparam of the j-th
// differentiable parameter component (table order), for random w: the same numbers up to
// rounding (the separate entries are checked by jacobian_products and dparam).
CheckResult Checker::adjoint_products_check() {
  CheckResult r{"adjoint_products",
                "fused products against add_jacobian_products and w . add_dforce_dparam, random w",
                CheckStatus::Pass,
                0.0,
                opt_.identity_tolerance,
                ""};
  if (!(t_->capabilities & PINSIM_CAP_ADJOINT_PRODUCTS) || t_->add_adjoint_products == nullptr ||
      t_->add_jacobian_products == nullptr || t_->add_dforce_dparam == nullptr) {
    r.status = CheckStatus::Skip;
    r.detail = "no fused products (PINSIM_CAP_ADJOINT_PRODUCTS not declared)";
    return r;
  }
  const bool with_v = (t_->capabilities & PINSIM_CAP_DFDV) != 0;
  struct Slot {
    uint32_t param, component;
  };
  std::vector<Slot> slots;
  for (uint32_t i = 0; i < t_->n_params; ++i)
    if (t_->params[i].flags & PINSIM_PARAM_DIFFERENTIABLE)
      for (uint32_t c = 0; c < (t_->params[i].type == PINSIM_PARAM_VEC2 ? 2u : 1u); ++c)
        slots.push_back({i, c});
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample s = random_state();
    auto inst = make(init);
    const VectorXd w = random_field(s);
    VectorXd gx, gv, gp;
    inst->adjoint_products(s, w, with_v, static_cast<uint32_t>(slots.size()), gx, gv, gp);
    const std::string state = "state " + std::to_string(trial) + ", ";
    for (int which = 0; which < (with_v ? 2 : 1); ++which) {
      const VectorXd want = inst->jacobian_product(s, w, which);
      const VectorXd& got = which == 0 ? gx : gv;
      Eigen::Index at = 0;
      const double e = rel(got, want, &at);
      const Eigen::Index j = at / 1000;
      keep_worst(r, e, e <= r.tolerance,
                 state + (which == 0 ? "(df/dx)" : "(df/dv)") + "^T w at " + dof_name(j) +
                     ": fused " + num(got[j], 6) + ", add_jacobian_products " + num(want[j], 6) +
                     "; error " + num(e, 3));
    }
    for (std::size_t k = 0; k < slots.size(); ++k) {
      const VectorXd df = inst->dforce_dparam(s, slots[k].param, slots[k].component);
      const double want = w.dot(df), got = gp[static_cast<Eigen::Index>(k)];
      // relative to the terms summed, not to the sum alone (which may cancel to ~0)
      const double scale = w.cwiseAbs().dot(df.cwiseAbs());
      const double e = scale > 0.0 ? std::abs(got - want) / scale : std::abs(got);
      const pinsim_param& p = t_->params[slots[k].param];
      const std::string what =
          std::string(p.name) +
          (p.type == PINSIM_PARAM_VEC2 ? (slots[k].component == 0 ? "[0]" : "[1]") : "");
      keep_worst(r, e, e <= r.tolerance,
                 state + "w . d f / d " + what + ": fused " + num(got, 6) +
                     ", w . add_dforce_dparam " + num(want, 6) + "; error " + num(e, 3));
    }
  }
  return r;
}

}  // namespace pinsim::plugin_check
