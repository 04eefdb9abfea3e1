// What an integrator's stages see of a step: the state they move, the forces at any state,
// and the forces' Jacobians. Simulation::step makes one per step; the drift, its contacts
// and the checks stay with the step.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <pinsim/state.hpp>
#include <string>
#include <vector>

#include "core/plugin_instance.hpp"

namespace pinsim {

class Simulation;

class StepContext {
 public:
  explicit StepContext(Simulation& sim) : sim_(sim) {}

  /// The state the step moves; its time is the step's start until the step's bookkeeping.
  State& state() const;
  /// The step being taken, counting from 1 (for NumericError).
  uint64_t step() const;
  /// The scene's forces in scene order (their flags: velocity_dependent(), concurrent()).
  const std::vector<std::unique_ptr<ForceInstance>>& forces() const;

  /// f = the sum of all forces at s (f resized to 2xN and zeroed first); with `include`, of
  /// the forces k with (*include)[k] != 0 only. Throws NumericError naming the plugin and the
  /// particle of a non-finite force.
  void compute_forces(const State& s, Eigen::Matrix2Xd& f,
                      const std::vector<char>* include = nullptr) const;
  /// "forces[2] 'damped_spring'": force k by its place in the scene's forces array.
  std::string force_label(std::size_t k) const;
  /// Threads the run may use (--threads resolved).
  std::size_t threads() const;

  /// Force k's Jacobian entries at s, df/dx into dfdx and df/dv into dfdv, in the order the
  /// force emits them (single entries through add, 2x2 blocks through add_blocks if the sink
  /// has it, else add); central finite differences of its force where the plugin gives no
  /// Jacobian (a one-time warning names it; df/dv only for forces that may depend on v). May
  /// run for two forces at once on two threads, provided no two instances of one plugin
  /// without PINSIM_CAP_CONCURRENT (ForceInstance::concurrent) run at once. A caller that
  /// asks every force calls count_jacobian_evaluation() once (Simulation's counter).
  void jacobians(std::size_t k, const State& s, const pinsim_triplet_sink& dfdx,
                 const pinsim_triplet_sink& dfdv) const;
  void count_jacobian_evaluation() const;

  /// "forces[2] 'damped_spring'": the force whose Jacobian weighs most in implicit Euler's
  /// system M - h df/dv - h^2 df/dx at s, the largest (h^2 |df/dx| + h |df/dv|) / m over the
  /// entries of free rows in `weight`; "" if no force has a Jacobian entry.
  std::string stiffest_force(const State& s, double h, double& weight) const;

 private:
  Simulation& sim_;
};

}  // namespace pinsim
