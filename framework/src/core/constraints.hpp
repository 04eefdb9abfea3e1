// The scene's forces as soft constraints, one view for every consumer (XPBD, check-plugin,
// gradients). A force that reports constraints (PINSIM_CAP_CONSTRAINTS, pinsim/abi.h) is
//   E = sum_e ks_e/2 C_e(x)^2 + const,   f = -sum_e J_e^T (ks_e C_e + kd_e J_e v),  J_e = dC_e/dx
// (seed lecture, "Generalized spring model"); this module reads each such force's constraint
// set once, checks it, and evaluates C and dC/dp of any list of constraints.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "core/plugin_instance.hpp"

namespace pinsim {

/// Every constraint of a list of forces, numbered force by force in each force's element order
/// (the global id j). Holds pointers to the forces: they must outlive it.
class ConstraintSystem {
 public:
  /// The constraints of every force in `forces` that provides them, checked against the state
  /// of `n_particles` particles: indices in range, arity as declared, ks and kd finite or +inf
  /// and >= 0. `labels[k]` names force k in errors ("forces[1] 'bending'"). Throws PluginError.
  static ConstraintSystem gather(const std::vector<std::unique_ptr<ForceInstance>>& forces,
                                 const std::vector<std::string>& labels, std::size_t n_particles);

  /// Number of constraints.
  std::size_t size() const { return element_.size(); }
  /// Whether force k provides constraints (its constraints are in the system).
  bool covers(std::size_t k) const { return k < covers_.size() && covers_[k] != 0; }
  /// Index (into the forces given to gather) of the force constraint j belongs to.
  uint32_t force(std::size_t j) const { return force_[j]; }
  /// The element of its force that constraint j is.
  uint64_t element(std::size_t j) const { return element_[j]; }
  /// The particles of constraint j, in its order.
  std::span<const uint32_t> particles(std::size_t j) const {
    return {particles_.data() + start_[j], start_[j + 1] - start_[j]};
  }
  double ks(std::size_t j) const { return ks_[j]; }
  double kd(std::size_t j) const { return kd_[j]; }

  /// For the n constraints ids[0..n) with elements[k] = element(ids[k]): c[k] = C and their
  /// dC/dp one after another into dc (2 L doubles each, x then y per particle), at positions x
  /// (2 per particle). Consecutive ids of one force go to the plugin in one call. Reads only:
  /// may run on several threads at once with their own arrays. Throws PluginError.
  void evaluate(const double* x, const uint32_t* ids, const uint64_t* elements, std::size_t n,
                double* c, double* dc) const;
  /// evaluate for n elements of force k (one plugin call): c[q] = C of elements[q], its dC/dp
  /// into dc, one constraint after another.
  void evaluate_force(uint32_t k, const double* x, const uint64_t* elements, std::size_t n,
                      double* c, double* dc) const {
    forces_[k]->constraints(x, elements, n, c, dc);
  }

 private:
  std::vector<const ForceInstance*> forces_;
  std::vector<char> covers_;
  std::vector<uint32_t> force_;
  std::vector<uint64_t> element_;
  std::vector<std::size_t> start_;  ///< constraint j's particles: particles_[start_[j] ..)
  std::vector<uint32_t> particles_;
  std::vector<double> ks_, kd_;
};

}  // namespace pinsim
