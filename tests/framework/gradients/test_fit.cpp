// The L-BFGS-B driver on functions with known minima.
#include <catch2/catch.hpp>
#include <cmath>

#include "gradients/fit.hpp"

using namespace pinsim::grad;

// Rosenbrock (1 - a)^2 + 100 (b - a^2)^2, minimum at (1, 1), from (-1.2, 1).
TEST_CASE("fit: Rosenbrock to its minimum, every iteration reported", "[gradients][fit]") {
  std::vector<FitVariable> v = {{"a", -1.2, -5.0, 5.0}, {"b", 1.0, -5.0, 5.0}};
  int reported = 0;
  double last = HUGE_VAL;
  bool decreasing = true;
  const FitResult r = fit_lbfgsb(
      v,
      [](const Eigen::VectorXd& x, Eigen::VectorXd& g) {
        const double a = x[0], b = x[1];
        g[0] = -2.0 * (1.0 - a) - 400.0 * a * (b - a * a);
        g[1] = 200.0 * (b - a * a);
        return (1.0 - a) * (1.0 - a) + 100.0 * (b - a * a) * (b - a * a);
      },
      FitOptions{},
      [&](const FitIteration& it) {
        CHECK(it.iteration == reported);
        ++reported;
        decreasing = decreasing && it.loss <= last;
        last = it.loss;
      });
  CHECK(decreasing);
  CHECK(reported == r.iterations + 1);
  CHECK(r.x[0] == Approx(1.0).epsilon(1e-6));
  CHECK(r.x[1] == Approx(1.0).epsilon(1e-6));
}

// A bound that binds: (a - 3)^2 with a in [0, 2] ends at a = 2.
TEST_CASE("fit: bounds hold", "[gradients][fit]") {
  std::vector<FitVariable> v = {{"a", 0.5, 0.0, 2.0}};
  const FitResult r = fit_lbfgsb(
      v,
      [](const Eigen::VectorXd& x, Eigen::VectorXd& g) {
        g[0] = 2.0 * (x[0] - 3.0);
        return (x[0] - 3.0) * (x[0] - 3.0);
      },
      FitOptions{}, nullptr);
  CHECK(r.x[0] == Approx(2.0).epsilon(1e-12));
  CHECK_THROWS_AS(
      fit_lbfgsb(
          {{"a", 5.0, 0.0, 2.0}}, [](const Eigen::VectorXd&, Eigen::VectorXd&) { return 0.0; },
          FitOptions{}, nullptr),
      std::invalid_argument);
}
