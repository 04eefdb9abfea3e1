// The constraints XPBD solves, laid out once for its sweeps: coloured (constraint_colouring),
// then stored in colour order with their particles, inverse masses and coefficients side by
// side, so a sweep reads each array front to back and calls the plugins once per chunk.
#pragma once

#include <cstddef>
#include <cstdint>
#include <pinsim/state.hpp>
#include <span>
#include <vector>

#include "core/constraint_colouring.hpp"
#include "core/constraints.hpp"

namespace pinsim {

/// A subset of a ConstraintSystem's constraints in colour order, with the two sweeps of a
/// substep of step h over them:
///  - project: compliant position projection (Macklin et al. 2016, eq. 18 with the damping of
///    eq. 26), for constraints with ks > 0;
///  - damp: the implicit (backward Euler) velocity update of a pure damper f = -kd J^T J v, for
///    constraints with ks = 0 and kd > 0.
/// Both process one colour's range [b, e) of positions q (colour order); the constraints of a
/// colour share no moving particle, so ranges of one colour can run on different threads.
class XpbdConstraints {
 public:
  /// What project and damp return when every update stayed finite.
  static constexpr std::size_t kFine = ~std::size_t{0};

  /// The constraints j of `system` with include[j] != 0, coloured with `moves` (particles
  /// with inverse mass > 0), with the inverse masses `inv_mass`, read once: a run's masses
  /// and pins do not change. Keeps a pointer to `system`, which must outlive it.
  XpbdConstraints(const ConstraintSystem& system, const std::vector<char>& include,
                  const std::vector<char>& moves, const Eigen::VectorXd& inv_mass);
  XpbdConstraints() = default;

  std::size_t size() const { return ids_.size(); }
  std::size_t colours() const { return colouring_.colours(); }
  /// Positions [begin(c), begin(c + 1)) are colour c.
  std::size_t begin(std::size_t c) const { return colouring_.start[c]; }
  /// The system's id of the constraint at position q.
  uint32_t id(std::size_t q) const { return ids_[q]; }
  /// The particles of the constraint at position q.
  std::span<const uint32_t> particles(std::size_t q) const {
    return {particles_.data() + slot_[q], slot_[q + 1] - slot_[q]};
  }
  /// C of the constraint at position q as last evaluated by project or damp.
  double c(std::size_t q) const { return c_[q]; }

  /// Sets the step h the coefficients below are for (recomputed only when h changes).
  void set_step(double h);

  /// One sweep's projection of positions [b, e) onto p (2 per particle) from the substep's
  /// start positions x: C and dC/dp at p from the plugins, then for each constraint
  ///   dlambda = (-C - alpha~ lambda - gamma J (p - x)) / ((1 + gamma) sum_i w_i |J_i|^2 + alpha~)
  ///   lambda += dlambda;  p_i += w_i J_i dlambda  (moving particles only),
  /// with lambda = 0 before the first sweep. Returns the first position whose update made a
  /// coordinate of p non-finite (p then holds it), or kFine.
  std::size_t project(const double* x, double* p, bool first_sweep, bool keep_lambda, std::size_t b,
                      std::size_t e);

  /// The dampers [b, e) on the velocities v at positions x: for each, with J at x,
  ///   v_i -= h kd w_i J_i (J v) / (1 + h kd sum_k w_k |J_k|^2),
  /// which is v' = v + h M^-1 f(v') for f = -kd J^T J v' of this one damper (backward Euler).
  /// Returns the first position whose update made a velocity non-finite, or kFine.
  std::size_t damp(const double* x, double* v, std::size_t b, std::size_t e);

 private:
  template <uint32_t M>
  std::size_t project_arity(const double* x, double* p, bool first_sweep, bool keep_lambda,
                            std::size_t b, std::size_t e);
  /// c_ and dc_ of positions [b, e) at positions x.
  void evaluate(const double* x, std::size_t b, std::size_t e);
  /// The first position in [b, e) with a moving particle whose coordinate in `out` is not
  /// finite.
  std::size_t first_non_finite(const double* out, std::size_t b, std::size_t e) const;

  const ConstraintSystem* system_ = nullptr;
  ConstraintColouring colouring_;
  uint32_t arity_ = 0;  ///< the constraints' common number of particles, 0 if they differ
  double h_ = 0.0;      ///< the step of at_ and gamma_
  // per position q (colour order)
  std::vector<uint32_t> ids_;
  std::vector<uint64_t> elements_;
  std::vector<std::size_t> run_end_;  ///< the first position after q of another force
  std::vector<std::size_t> slot_;     ///< its particles: particles_[slot_[q] .. slot_[q + 1])
  std::vector<uint32_t> particles_;
  std::vector<double> w_;  ///< inverse mass of each particles_ entry
  std::vector<double> ks_, kd_;
  std::vector<double> at_;     ///< alpha~ = 1 / (ks h^2)
  std::vector<double> gamma_;  ///< alpha~ kd h (0 without damping)
  std::vector<double> lambda_, c_, dl_;
  std::vector<double> dc_;  ///< dC/dp, 2 per particles_ entry
};

}  // namespace pinsim
