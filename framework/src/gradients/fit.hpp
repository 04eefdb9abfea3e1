// Bounded least squares (or any smooth loss) over a few scene values: L-BFGS-B from LBFGS++
// (Debian's liblbfgspp-dev), with an iteration callback.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

namespace pinsim::grad {

/// One value being fitted.
struct FitVariable {
  std::string name;                            ///< its --set path
  double start = 0.0;                          ///< initial value
  double lower = -HUGE_VAL, upper = HUGE_VAL;  ///< bounds (inclusive)
};

struct FitOptions {
  int max_iterations = 200;
  /// Stop when the projected gradient (in variables scaled by their starting size) falls to
  /// this fraction of its starting norm.
  double gradient_tolerance = 1e-9;
};

/// One accepted iterate.
struct FitIteration {
  int iteration = 0;    ///< 0: the start
  int evaluations = 0;  ///< objective evaluations so far
  double loss = 0.0;
  Eigen::VectorXd x, g;  ///< the values and the loss's gradient in them
};

struct FitResult {
  Eigen::VectorXd x;  ///< the best values found
  double loss = 0.0;  ///< and their loss
  int iterations = 0, evaluations = 0;
  std::string stop;  ///< why it stopped
};

/// loss(x, g): the loss at x, its gradient into g (sized like x).
using FitObjective = std::function<double(const Eigen::VectorXd& x, Eigen::VectorXd& g)>;

/// Minimizes `loss` over the variables within their bounds by L-BFGS-B (LBFGS++'s
/// LBFGSBSolver, More-Thuente line search), in variables scaled by max(|start|, 1e-3 of the
/// bound range, 1e-12) so that each starts near unit size. Calls on_iteration for the start and
/// after each accepted step. Throws std::invalid_argument for a start outside its bounds.
FitResult fit_lbfgsb(const std::vector<FitVariable>& vars, const FitObjective& loss,
                     const FitOptions& options,
                     const std::function<void(const FitIteration&)>& on_iteration);

}  // namespace pinsim::grad
