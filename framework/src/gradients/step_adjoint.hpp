// The adjoint of one time step for each integrator that can be differentiated: from the
// adjoints of the state after the step to those of the state before it, given what the
// step did (a StepTape) and the forces' Jacobian products (docs/gradients.md).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <pinsim/state.hpp>
#include <string>

#include "core/block_krylov.hpp"
#include "gradients/drift_adjoint.hpp"
#include "gradients/drift_tape.hpp"
#include "gradients/force_model.hpp"

namespace pinsim::grad {

/// The integrators with an adjoint step.
enum class Scheme : uint8_t { kSymplecticEuler, kVelocityVerlet, kImplicitEuler };

/// The scheme for a scene's integrator name; false (and `why` says so) for one without an
/// adjoint step.
bool scheme_for(const std::string& integrator, Scheme& out, std::string& why);

/// What one step did, as far as its adjoint needs it.
struct StepTape {
  State start;      ///< the state entering the step
  DriftTape drift;  ///< the drift, entered at (drift.x_in, drift.v_in)
  /// Velocity Verlet: the positions after the drift, the velocities after the impact
  /// correction and, with velocity-dependent forces, the predictor's velocities.
  Eigen::Matrix2Xd x1, vc, vp;
  bool predicted = false;
  /// Implicit Euler: A^T of the step's system as its replay assembled it (has_system), and
  /// whether A is symmetric (the adjoint step of implicit Euler requires it).
  BlockSystem system;
  bool has_system = false, symmetric = false;
};

/// The adjoint of a run's state at one time, and of its parameters so far.
struct Adjoint {
  Eigen::Matrix2Xd gx, gv;  ///< d L / d x, d L / d v of the state
  Eigen::VectorXd gp;       ///< d L / d theta of the force parameters (ForceModel::param_vjp)
  MaterialGrad material;    ///< d L / d (restitution, friction, kick) per obstacle
  /// Velocity Verlet with a model that splits: the opening kick's product for the
  /// position-only forces, w at the state entering the step, not yet added (the earlier
  /// step's kicks at the same positions take it into theirs; adjoint_finish adds what is
  /// left).
  Eigen::Matrix2Xd pending_w;
  State pending_at;
  bool pending = false;
  /// Storage of the adjoint steps, reused from step to step (no allocation per step).
  struct Scratch {
    State s1, s2;
    Eigen::Matrix2Xd gx1, vc_bar, vp_bar, w, w_pos, a0_bar, unused;
    BlockKrylov krylov;          ///< implicit Euler's transposed solves
    Eigen::VectorXd mu, rhs, r;  ///< their solution (the next solve's guess), right side
  } scratch;

  /// Zero adjoints for n particles and p parameter components.
  void reset(Eigen::Index n, Eigen::Index p);
};

/// Figures of the adjoint steps (for gradient.json).
struct AdjointStats {
  uint64_t steps = 0;
  uint64_t solves = 0;            ///< implicit Euler's transposed solves
  uint64_t solve_iterations = 0;  ///< their Krylov iterations
  uint64_t lu_fallbacks = 0;      ///< solves that fell back to sparse LU
  double worst_residual = 0.0;    ///< largest relative residual of a transposed solve
};

/// Symplectic Euler, v' = v + h M^-1 f(x, v), then the drift with v'.
void adjoint_symplectic_euler(ForceModel& forces, const StepTape& tape, double h, Adjoint& a);

/// Velocity Verlet (integrator_verlet.cpp): half kick, drift, the impact correction of
/// correct_impacts, the closing half kick at the drift's end (through the predictor when
/// tape.predicted).
void adjoint_velocity_verlet(ForceModel& forces, const StepTape& tape, double h, Adjoint& a);

/// Linearized backward Euler (integrator_implicit_euler.cpp): (M - h D - h^2 K) dv =
/// h (f + h K v), then the drift with v + dv = tape.drift.v_in. The adjoint solves the
/// transposed system A^T mu = (adjoint of dv); the second-order terms (A and b depend on
/// the state through K and D) are directional derivatives of the forces' Jacobian products,
/// by central differences along the one direction (h^2 v', h dv) that they need.
void adjoint_implicit_euler(ForceModel& forces, const StepTape& tape, double h, Adjoint& a,
                            AdjointStats& stats);

/// Adds what the adjoint steps deferred (Adjoint::pending); call after the last (earliest)
/// step, before reading the adjoints of the initial state and the parameters.
void adjoint_finish(ForceModel& forces, Adjoint& a);

/// The adjoint step of `scheme`.
void adjoint_step(Scheme scheme, ForceModel& forces, const StepTape& tape, double h, Adjoint& a,
                  AdjointStats& stats);

}  // namespace pinsim::grad
