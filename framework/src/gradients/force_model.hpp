// What the adjoint of a step needs of the forces: their value, the transposed products of
// their Jacobians, and their derivatives in the parameters being differentiated.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <pinsim/state.hpp>
#include <stdexcept>

namespace pinsim::grad {

class ForceModel {
 public:
  /// Which forces a product covers: all of them, those that may depend on the velocities,
  /// or the others (their values and Jacobians depend on the positions only, df/dv = 0).
  enum class Part : uint8_t { kAll, kVelocityDependent, kPositionOnly };

  virtual ~ForceModel() = default;
  /// f = the total force at s (2xN).
  virtual void force(const State& s, Eigen::Matrix2Xd& f) = 0;
  /// gx += (df/dx)^T w and gv += (df/dv)^T w at s (all 2xN).
  virtual void vjp(const State& s, const Eigen::Matrix2Xd& w, Eigen::Matrix2Xd& gx,
                   Eigen::Matrix2Xd& gv) = 0;
  /// gp += (df/dtheta)^T w at s: one entry per differentiated parameter component.
  virtual void param_vjp(const State& s, const Eigen::Matrix2Xd& w, Eigen::VectorXd& gp) = 0;
  /// Whether some force may depend on the velocities (velocity Verlet's predictor runs then).
  virtual bool velocity_dependent() const = 0;
  /// Whether vjp_part and param_vjp_part take a part other than kAll.
  virtual bool splits() const { return false; }
  /// vjp over the forces of `part` only (kPositionOnly: gv is left as it is).
  virtual void vjp_part(Part part, const State& s, const Eigen::Matrix2Xd& w, Eigen::Matrix2Xd& gx,
                        Eigen::Matrix2Xd& gv) {
    if (part != Part::kAll)
      throw std::logic_error("ForceModel: vjp_part of a model that does not split");
    vjp(s, w, gx, gv);
  }
  /// param_vjp over the forces of `part` only.
  virtual void param_vjp_part(Part part, const State& s, const Eigen::Matrix2Xd& w,
                              Eigen::VectorXd& gp) {
    if (part != Part::kAll)
      throw std::logic_error("ForceModel: param_vjp_part of a model that does not split");
    param_vjp(s, w, gp);
  }
  /// vjp_part and param_vjp_part at the same s and w, in one call: a model whose forces give
  /// both in one pass over their elements overrides it.
  virtual void vjp_with_params(Part part, const State& s, const Eigen::Matrix2Xd& w,
                               Eigen::Matrix2Xd& gx, Eigen::Matrix2Xd& gv, Eigen::VectorXd& gp) {
    vjp_part(part, s, w, gx, gv);
    param_vjp_part(part, s, w, gp);
  }
  /// gp += d/dtheta [w^T (K a + D c)] at s: the Jacobian products' derivatives in the
  /// parameters along the directions a (of x) and c (of v). By default the directional
  /// derivative d/deps [(df/dtheta)(x + eps a, v + eps c)^T w] by central differences of
  /// param_vjp with step eps (truncation O(eps^2); a param_vjp that is itself a difference
  /// quotient has its rounding amplified by 1/eps: a model that can, overrides this).
  virtual void param_jacobian_vjp(const State& s, const Eigen::Matrix2Xd& w,
                                  const Eigen::Matrix2Xd& a, const Eigen::Matrix2Xd& c, double eps,
                                  Eigen::VectorXd& gp) {
    State sp = s, sm = s;
    sp.x += eps * a;
    sp.v += eps * c;
    sm.x -= eps * a;
    sm.v -= eps * c;
    Eigen::VectorXd pp = Eigen::VectorXd::Zero(gp.size()), pm = pp;
    param_vjp(sp, w, pp);
    param_vjp(sm, w, pm);
    gp += (pp - pm) / (2.0 * eps);
  }
};

}  // namespace pinsim::grad
