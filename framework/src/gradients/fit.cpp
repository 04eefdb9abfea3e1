#include "gradients/fit.hpp"

#include <LBFGSB.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace pinsim::grad {
namespace {

using Vec = Eigen::VectorXd;

/// The objective in scaled variables z (x = scale z), remembering the best point and the
/// last evaluation (the solver's first call repeats the start).
struct Scaled {
  const FitObjective* loss = nullptr;
  Vec scale;
  const std::function<void(const FitIteration&)>* on_iteration = nullptr;
  int evaluations = 0, iterations = 0;
  Vec last_z, last_g;
  double last_f = 0.0;
  Vec best_x;
  double best_f = HUGE_VAL;

  double operator()(const Vec& z, Vec& gz) {
    if (last_z.size() == z.size() && last_z == z) {
      gz = last_g;
      return last_f;
    }
    const Vec x = scale.cwiseProduct(z);
    Vec g = Vec::Zero(x.size());
    const double f = (*loss)(x, g);
    ++evaluations;
    gz = scale.cwiseProduct(g);
    last_z = z;
    last_g = gz;
    last_f = f;
    if (std::isfinite(f) && f < best_f) {
      best_f = f;
      best_x = x;
    }
    return f;
  }
  /// An accepted iterate (from the line search below).
  void accepted(double f, const Vec& z, const Vec& gz) {
    ++iterations;
    report(f, z, gz);
  }
  void report(double f, const Vec& z, const Vec& gz) const {
    if (!*on_iteration) return;
    FitIteration it;
    it.iteration = iterations;
    it.evaluations = evaluations;
    it.loss = f;
    it.x = scale.cwiseProduct(z);
    it.g = gz.cwiseQuotient(scale);
    (*on_iteration)(it);
  }
};

/// LBFGS++'s More-Thuente line search, then the iteration callback: the solver calls its
/// line search once per iteration and accepts the point it returns.
template <class Scalar>
struct ReportingLineSearch {
  template <class Foo>
  static void LineSearch(Foo& f, Scalar& fx, Vec& x, Vec& grad, Scalar& step,
                         const Scalar& step_max, const Vec& drt, const Vec& xp,
                         const LBFGSpp::LBFGSBParam<Scalar>& param) {
    LBFGSpp::LineSearchMoreThuente<Scalar>::LineSearch(f, fx, x, grad, step, step_max, drt, xp,
                                                       param);
    f.accepted(fx, x, grad);
  }
};

}  // namespace

FitResult fit_lbfgsb(const std::vector<FitVariable>& vars, const FitObjective& loss,
                     const FitOptions& options,
                     const std::function<void(const FitIteration&)>& on_iteration) {
  const auto n = static_cast<Eigen::Index>(vars.size());
  Scaled obj;
  obj.loss = &loss;
  obj.on_iteration = &on_iteration;
  obj.scale.resize(n);
  Vec z0(n), lb(n), ub(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const FitVariable& v = vars[static_cast<std::size_t>(k)];
    if (!(v.start >= v.lower && v.start <= v.upper))
      throw std::invalid_argument(v.name + ": the start " + std::to_string(v.start) +
                                  " is outside its bounds");
    const double range = v.upper - v.lower;
    double s = std::abs(v.start);
    if (std::isfinite(range)) s = std::max(s, 1e-3 * range);
    s = std::max(s, 1e-12);
    obj.scale[k] = s;
    z0[k] = v.start / s;
    lb[k] = v.lower / s;
    ub[k] = v.upper / s;
  }
  // the start, once: its gradient sets the stopping threshold
  Vec g0;
  const double f0 = obj(z0, g0);
  obj.report(f0, z0, g0);
  FitResult out;
  LBFGSpp::LBFGSBParam<double> param;
  param.max_iterations = options.max_iterations;
  param.epsilon = options.gradient_tolerance * g0.norm();
  param.epsilon_rel = 0.0;
  // LBFGSBParam's defaults also stop when the loss changes by less than delta = 1e-10 in
  // absolute terms (past = 1), which ends a misfit near zero long before its minimum.
  param.past = 0;
  param.max_linesearch = 40;
  Vec z = z0;
  double fz = f0;
  try {
    LBFGSpp::LBFGSBSolver<double, ReportingLineSearch> solver(param);
    solver.minimize(obj, z, fz, lb, ub);
    out.stop = obj.iterations >= options.max_iterations && options.max_iterations > 0
                   ? "the iteration limit"
                   : "the projected gradient fell below the tolerance";
  } catch (const std::exception& e) {
    // the line search finds no decrease near a minimum reached to rounding, or fails
    out.stop = std::string("the line search stopped: ") + e.what();
  }
  out.x = obj.best_x;
  out.loss = obj.best_f;
  out.iterations = obj.iterations;
  out.evaluations = obj.evaluations;
  return out;
}

}  // namespace pinsim::grad
