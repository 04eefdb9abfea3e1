// check-plugin's engine: random states around the plugin's element layout, finite-difference
// helpers, and the checks, each returning one CheckResult (derivative_checks.cpp,
// identity_checks.cpp, degenerate_check.cpp; run() in plugin_check.cpp).
#pragma once

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <string>

#include "core/input_error.hpp"
#include "core/param_validation.hpp"
#include "tools/check_instance.hpp"
#include "tools/plugin_check.hpp"

namespace pinsim::plugin_check {

using Eigen::Matrix2Xd;
using Eigen::MatrixXd;
using Eigen::Vector2d;
using Eigen::VectorXd;

/// The engine: owns the random generator and the element list.
class Checker {
 public:
  Checker(const LoadedPlugin& p, const CheckOptions& o) : plugin_(p), t_(p.table), opt_(o) {
    rng_.seed(o.seed);
    if (o.scene != nullptr) {
      const ForceSpec& f = o.scene->forces[o.force_index];
      if (f.name != t_->name)
        throw InputError(f.where + ".type: is '" + f.name + "', not the plugin checked ('" +
                         t_->name + "')");
      layout_ = scene_layout(*o.scene, o.force_index, t_->arity);
      nlohmann::json params = f.params.is_object() ? f.params : nlohmann::json::object();
      for (const auto& [k, v] : o.params.items()) params[k] = v;
      params_ = validate_params(*t_, params, f.where + ".params").dump();
    } else {
      layout_ = topology_layout(o.topology, t_->arity);
      params_ = validate_params(*t_, o.params, "check-plugin: params").dump();
    }
    n_ = layout_.n;
  }

  CheckReport run();

 private:
  // --- states -------------------------------------------------------------------------
  double uni(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng_); }
  /// A field over s's particles (2n values) uniform in [-1, 1]: the w of the product checks.
  VectorXd random_field(const Sample& s) {
    VectorXd w(static_cast<Eigen::Index>(2 * s.n()));
    for (Eigen::Index j = 0; j < w.size(); ++j) w[j] = uni(-1, 1);
    return w;
  }

  /// Random positions in [-1, 1]^2 at least 0.2 apart (or the layout's reference
  /// positions perturbed), random velocities, random masses (or the scene's).
  Sample random_state(bool moving = true) {
    Sample s;
    const auto n = static_cast<Eigen::Index>(n_);
    s.x.resize(2, n);
    s.v.resize(2, n);
    s.w.resize(n);
    s.r = VectorXd::Constant(n, 0.05);
    if (layout_.x.cols() == n) {
      for (Eigen::Index i = 0; i < n; ++i) {
        s.x.col(i) = layout_.x.col(i) + layout_.noise * Vector2d(uni(-1, 1), uni(-1, 1));
        s.v.col(i) = moving ? Vector2d(uni(-1, 1), uni(-1, 1)) : Vector2d::Zero();
        s.w[i] = uni(0.5, 2.0);
      }
      if (layout_.from_scene()) {
        s.w = layout_.inv_mass;
        s.r = layout_.radius;
      }
      return s;
    }
    for (Eigen::Index i = 0; i < n; ++i) {
      for (int tries = 0; tries < 1000; ++tries) {
        s.x.col(i) = Vector2d(uni(-1, 1), uni(-1, 1));
        bool ok = true;
        for (Eigen::Index j = 0; j < i; ++j) ok = ok && (s.x.col(i) - s.x.col(j)).norm() > 0.2;
        if (ok) break;
      }
      s.v.col(i) = moving ? Vector2d(uni(-1, 1), uni(-1, 1)) : Vector2d::Zero();
      s.w[i] = uni(0.5, 2.0);
    }
    return s;
  }

  /// The state instances are created from (rest lengths, angles, areas): a random one, or
  /// a scene's own initial state.
  Sample rest_state() {
    if (!layout_.from_scene()) return random_state();
    Sample s;
    s.x = layout_.x;
    s.v = layout_.v;
    s.w = layout_.inv_mass;
    s.r = layout_.radius;
    return s;
  }

  std::unique_ptr<Instance> make(const Sample& initial) {
    return std::make_unique<Instance>(t_, params_, initial, layout_);
  }
  /// An instance whose parameter `name` (component c of a vec2) is `value`, the others as
  /// checked.
  std::unique_ptr<Instance> make_with(const Sample& initial, const std::string& name, int c,
                                      double value) {
    nlohmann::json p = nlohmann::json::parse(params_);
    if (p.at(name).is_array())
      p[name][static_cast<std::size_t>(c)] = value;
    else
      p[name] = value;
    return std::make_unique<Instance>(t_, p.dump(), initial, layout_);
  }

  // --- finite differences ----------------------------------------------------------------
  /// Relative discrepancy between an analytic array and its finite-difference estimate.
  static double rel(const MatrixXd& a, const MatrixXd& fd, Eigen::Index* where) {
    const MatrixXd d = (a - fd).cwiseAbs();
    Eigen::Index r = 0, c = 0;
    const double m = d.maxCoeff(&r, &c);
    if (where) *where = r * 1000 + c;
    const double scale = a.cwiseAbs().maxCoeff() + fd.cwiseAbs().maxCoeff() + 1e-12;
    if (!std::isfinite(m)) return std::numeric_limits<double>::infinity();
    return m / scale;
  }

  /// Step-halving verdict: the error at h/2 is small, or it is moderate and shrank like
  /// a consistent (second order) difference quotient. A wrong formula keeps its error.
  bool converged(double e1, double e2) const {
    if (!(e2 <= opt_.fd_tolerance) && !(e2 <= 1e-3 && e2 <= 0.35 * e1)) return false;
    return std::isfinite(e2);
  }

  CheckResult gradient_check();
  CheckResult jacobian_check(int which);
  CheckResult momentum_check(bool angular);
  CheckResult invariance_check();
  CheckResult degenerate_check();
  CheckResult dissipation_check();
  CheckResult constraint_check(int which);
  CheckResult dparam_check();
  CheckResult products_check();
  CheckResult adjoint_products_check();

  /// Records a state's error; the reported worst is the worst failing one if any failed.
  static void keep_worst(CheckResult& r, double err, bool ok, const std::string& detail) {
    if (!std::isfinite(err)) err = std::numeric_limits<double>::infinity();
    const bool had_fail = r.status == CheckStatus::Fail;
    bool take = false;
    if (!ok)
      take = !had_fail || err > r.worst;
    else
      take = !had_fail && (r.detail.empty() || err > r.worst);
    if (!ok) r.status = CheckStatus::Fail;
    if (take) {
      r.worst = err;
      r.detail = detail;
    }
  }

  const LoadedPlugin& plugin_;
  const pinsim_plugin* t_;
  CheckOptions opt_;
  std::mt19937_64 rng_;
  CheckLayout layout_;
  std::size_t n_ = 6;
  std::string params_;
};

inline constexpr double kStep = 1e-4;  // finite-difference step at scene scale 1

}  // namespace pinsim::plugin_check
