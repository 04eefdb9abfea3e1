// The checks run after every step: a finite state, and a bound on the growth of each
// particle's kinetic energy that legitimate steps never reach.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <pinsim/parallel.hpp>
#include <pinsim/state.hpp>
#include <vector>

namespace pinsim {

/// What the check after a step found; `particle` is -1 when all is well.
struct StepFinding {
  enum class What { None, NonFinite, Growth };
  /// Where a non-finite value first appeared within the step.
  enum class Phase { BeforeDrift, Drift, AfterDrift };
  What what = What::None;
  Eigen::Index particle = -1;
  Phase phase = Phase::BeforeDrift;  ///< NonFinite only
  Eigen::Vector2d v_in;              ///< the particle's velocity entering the drift
  double k_prev = 0.0;               ///< Growth: K_i^n
  double k_free = 0.0;               ///< Growth: K_i^free
  double scale = 0.0;                ///< Growth: S_n
  explicit operator bool() const { return what != What::None; }
};

/// The growth bound, per particle i and step n -> n+1 (derivation in step_checks.cpp):
///   K_i^free > G (K_i^n + S_n)  fails the step, from the second step on,
/// where K_i^n = m_i |v_i^n|^2 / 2 at the end of step n, K_i^free is the same for the end
/// velocity without the change the backend made during its drift (contacts), S_n is the
/// largest total kinetic energy so far (either kind) or the scene's initial energy scale,
/// and G = checks.kinetic_growth (0 turns the bound off).
class StepChecks {
 public:
  /// `scale0`: the initial energy scale, K^0 + sum |U_f(x^0)|; `growth`: G (0 = off).
  void start(const State& s, double scale0, double growth);
  /// Around the backend's drift: the velocities entering and leaving it.
  void before_drift(const State& s) { copy(s.v, v_in_); }
  void after_drift(const State& s) {
    copy(s.v, v_out_);
    drifted_ = true;
  }
  /// Where the velocities entering the drift go when the kick before it fills them in its
  /// own pass (kick()'s copy), in place of before_drift's copy.
  Eigen::Matrix2Xd& entering_drift() { return v_in_; }
  /// Around a step of several drifts (substeps): begin_drifts before the first, the substep
  /// pair around each drift, end_drifts after the last; check() then takes out the sum of
  /// the velocity changes of all the drifts.
  /// after_substep_drift also checks that x and v are finite, so a non-finite value made by
  /// a drift is found in its substep (not in the next substep's stages, which would spread
  /// it); a finding then has the phase Drift, or BeforeDrift if v entered the drift
  /// non-finite.
  void begin_drifts(const State& s) { drift_change_.setZero(2, s.v.cols()); }
  void before_substep_drift(const State& s) { copy(s.v, v_sub_); }
  StepFinding after_substep_drift(const State& s);
  void end_drifts() {
    v_in_.setZero(2, drift_change_.cols());
    v_out_ = drift_change_;
    drifted_ = true;
  }
  /// after_drift for a drift that ends the step (nothing changes s.v before check()): the
  /// velocities leaving it are s.v itself, which check() reads instead of a copy.
  void after_last_drift() {
    drifted_ = true;
    out_is_v_ = true;
  }
  /// After the step: finite x and v, then the growth bound. Only reads the state; on a
  /// finding the recorded energies stay those of the last good step.
  StepFinding check(const State& s);

 private:
  StepFinding non_finite(const State& s) const;
  StepFinding growth(const State& s) const;
  /// to = from, in fixed chunks of particles (on threads for large states).
  static void copy(const Eigen::Matrix2Xd& from, Eigen::Matrix2Xd& to) {
    if (from.cols() < static_cast<Eigen::Index>(kParallelItems))
      to = from;
    else
      copy_chunks(from, to);
  }
  static void copy_chunks(const Eigen::Matrix2Xd& from, Eigen::Matrix2Xd& to);

  /// One chunk's share of check()'s sums (combined in chunk order).
  struct Part {
    double poison = 0.0, k_sum = 0.0, kf_sum = 0.0;
    int over = 0;
  };
  std::vector<Part> parts_;

  double growth_ = 0.0;
  double scale_ = 0.0;  ///< S_n
  uint64_t steps_ = 0;
  bool drifted_ = false;
  bool out_is_v_ = false;       ///< after_last_drift: v_out_ is not filled, s.v holds it
  Eigen::VectorXd half_mass_;   ///< m_i / 2, 0 for pinned particles
  Eigen::VectorXd k_, k_next_;  ///< K_i^n, and K_i^{n+1} being computed
  Eigen::Matrix2Xd v_in_, v_out_;
  Eigen::Matrix2Xd v_sub_, drift_change_;  ///< substeps: v entering a drift, the sum of changes
};

}  // namespace pinsim
