// The adjoint of a drift: from the adjoints of the state leaving a backend's advance() to
// those of the state entering it, through every recorded impact (docs/gradients.md).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "gradients/drift_tape.hpp"

namespace pinsim::grad {

/// Adjoints of the contact materials, per obstacle index (grown as needed).
struct MaterialGrad {
  std::vector<double> restitution, friction, kick;
  double pair_restitution = 0.0;  ///< of the particle-particle contacts

  void add(int64_t obstacle, double de, double dmu, double dk);
  /// The entry of `v` for obstacle k, 0 if it has none.
  static double at(const std::vector<double>& v, int64_t k) {
    return k >= 0 && static_cast<std::size_t>(k) < v.size() ? v[static_cast<std::size_t>(k)] : 0.0;
  }
};

/// Adjoints that a consumer of an impact's own values adds on top of the state's (velocity
/// Verlet's impact correction reads the time of impact, the normal and the normal speed).
struct ImpactSeed {
  double tau = 0.0;  ///< on the time of impact
  Vec2 n{0.0, 0.0};  ///< on the normal
  double vn = 0.0;   ///< on the normal speed before the impulse, (v - u).n
};

/// The linearization of one obstacle impact (kToi or kInBand). Inputs, in order: the
/// position, velocity and time of the segment before it (p', w', tau': 2 + 2 + 1), then the
/// material (restitution, friction, kick); outputs: the position after it (pushed to the
/// offset if the march did), its velocity, time, normal (2) and normal speed before.
///   kToi:    d tau = -n.(dp' + s dw' - w' dtau') / (n.w' + phi_t),  s = tau - tau'
///            (the implicit function theorem on phi(p' + w' (tau - tau'), t0 + tau) = offset;
///            n.w' + phi_t = (w' - u).n for a rigid motion, < 0 when approaching)
///   kInBand: d tau = 0 (the march's time).
/// Then dn = H dp + n_t dtau, the contact point's and obstacle's velocity follow, and the
/// impulse w = w' - (1 + e)(vr.n) n - friction + kick n is differentiated in all of them.
using ImpactJacobian = Eigen::Matrix<double, 8, 8>;
ImpactJacobian impact_jacobian(const Impact& im, double tau_prev);

/// The linearization of one pair hit. Inputs: disc i's track (xr 2, tr 1, vc 2), disc j's
/// (5), the pair restitution; outputs: the two centres at the hit (2 + 2), its time, the two
/// velocity changes (2 + 2).
using PairJacobian = Eigen::Matrix<double, 9, 11>;
PairJacobian pair_jacobian(const PairHit& hit);

/// In place: (gx, gv), the adjoints of the positions and velocities leaving the drift
/// (2xN), become those of the state entering it; material adjoints are added to `mg`.
/// `seeds` (null, or one per tape.impacts entry) add adjoints on impacts' own values.
void drift_adjoint(const DriftTape& tape, Eigen::Matrix2Xd& gx, Eigen::Matrix2Xd& gv,
                   const std::vector<ImpactSeed>* seeds, MaterialGrad& mg);

/// Findings of the impacts themselves, added to `out`: grazing impacts (-vn below 1e-6 of
/// the speeds involved) and resting contacts (restitution dropped by rest_speed, or an
/// impulse inside the band), with the absolute time t0 + tau.
void assess_impacts(const DriftTape& tape, std::vector<Finding>& out);

}  // namespace pinsim::grad
