// check-plugin's checks of a force's constraint entry (PINSIM_CAP_CONSTRAINTS, pinsim/abi.h):
// the constraints against the plugin's own energy and force, and their gradients against
// central differences of C.
#pragma once

#include <pinsim/abi.h>

#include <Eigen/Core>
#include <functional>
#include <string>

namespace pinsim {

/// One instance's constraint entry and the functions the checks compare it with, at
/// positions x and velocities v (2n each, x0 y0 x1 y1 ...).
struct ConstraintProbe {
  pinsim_constraint_set set{};
  /// pinsim_plugin.constraints for the constraints `which`
  std::function<void(const double* x, const uint64_t* which, uint64_t count, double* c, double* dc)>
      constraints;
  std::function<double(const Eigen::VectorXd& x)> energy;  ///< empty without an energy
  std::function<Eigen::VectorXd(const Eigen::VectorXd& x, const Eigen::VectorXd& v)> force;
};

/// How far sum_e ks_e/2 C_e^2 is from the plugin's energy up to a constant: |dE - dU| /
/// (|dE| + |dU|) with dE = E(x) - E(x0) and dU the same of sum ks/2 C^2. `detail` says where.
double constraint_energy_error(const ConstraintProbe& p, const Eigen::VectorXd& x0,
                               const Eigen::VectorXd& x, std::string& detail);

/// How far -sum_e J_e^T (ks_e C_e + kd_e J_e v) is from add_force at (x, v): the largest
/// difference over the largest component of either.
double constraint_force_error(const ConstraintProbe& p, const Eigen::VectorXd& x,
                              const Eigen::VectorXd& v, std::string& detail);

/// How far every constraint's dC/dp is from central differences of C with step h: the
/// largest difference over the largest gradient component.
double constraint_gradient_error(const ConstraintProbe& p, const Eigen::VectorXd& x, double h,
                                 std::string& detail);

}  // namespace pinsim
