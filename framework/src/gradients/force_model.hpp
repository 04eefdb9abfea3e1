// What the adjoint of a step needs of the forces: their value, the transposed products of
// their Jacobians, and their derivatives in the parameters being differentiated.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <pinsim/state.hpp>

namespace pinsim::grad {

class ForceModel {
 public:
  virtual ~ForceModel() = default;
  /// f = the total force at s (2xN).
  virtual void force(const State& s, Eigen::Matrix2Xd& f) = 0;
  /// gx += (df/dx)^T w and gv += (df/dv)^T w at s (all 2xN).
  virtual void vjp(const State& s, const Eigen::Matrix2Xd& w, Eigen::Matrix2Xd& gx,
                   Eigen::Matrix2Xd& gv) = 0;
  /// gp += (df/dtheta)^T w at s: one entry per differentiated parameter component.
  virtual void param_vjp(const State& s, const Eigen::Matrix2Xd& w, Eigen::VectorXd& gp) = 0;
  /// K = df/dx and D = df/dv at s, 2N x 2N over dofs 2 * particle + component.
  virtual void jacobians(const State& s, Eigen::SparseMatrix<double>& K,
                         Eigen::SparseMatrix<double>& D) = 0;
  /// Whether some force may depend on the velocities (velocity Verlet's predictor runs then).
  virtual bool velocity_dependent() const = 0;
};

}  // namespace pinsim::grad
