// What a differentiable backend records of one drift (the position update over a step with
// its contacts), so that the adjoint can differentiate it: per impact the time of impact,
// the normal and its derivatives, the obstacle's velocity there and its material; per
// particle-particle contact the two discs' linear tracks. docs/gradients.md.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace pinsim::grad {

using Vec2 = Eigen::Vector2d;
using Mat2 = Eigen::Matrix2d;

/// How an impact's time and place are determined.
enum class ImpactKind : uint8_t {
  /// The path reached the contact offset: phi(p, t0 + tau) = offset, with p = p' + w' (tau -
  /// tau'); tau follows from the implicit function theorem (the time-of-impact rule).
  kToi,
  /// An impulse at a point already inside the contact band (a persistent or resting
  /// contact): its time is the march's, not a root of phi; the position is pushed back to
  /// the offset when it lies below it.
  kInBand,
  /// A velocity change scheduled by a particle-particle contact (PairHit `pair`, disc `side`)
  /// at the pair's time of impact.
  kChange
};

/// One velocity change of one particle within a drift.
struct Impact {
  ImpactKind kind = ImpactKind::kToi;
  uint32_t particle = 0;
  double tau = 0.0;  ///< time into the drift, s
  Vec2 p{0.0, 0.0};  ///< the particle's centre at the impact (before a push to the offset)
  Vec2 v_before{0.0, 0.0}, v_after{0.0, 0.0};  ///< its velocity before and after, units/s

  // Obstacle impacts (kToi, kInBand).
  int64_t obstacle = -1;     ///< index into the scene's "obstacles"
  Vec2 n{0.0, 1.0};          ///< unit normal grad phi at (p, t)
  Mat2 n_p = Mat2::Zero();   ///< d n / d p = the Hessian of phi, 1/length
  Vec2 n_t{0.0, 0.0};        ///< d n / d t at fixed p, 1/s
  double phi = 0.0;          ///< phi(p, t): the centre's signed distance, length
  double phi_t = 0.0;        ///< d phi / d t at fixed p (-n.u for a rigid motion), length/s
  double offset = 0.0;       ///< radius + depth_min: the level the march stops at, length
  Vec2 u{0.0, 0.0};          ///< the obstacle's velocity at the contact point p - phi n
  Mat2 u_p = Mat2::Zero();   ///< d u / d q at the contact point, 1/s
  Vec2 u_t{0.0, 0.0};        ///< d u / d t there, length/s^2
  double restitution = 0.0;  ///< the obstacle's material
  double friction = 0.0;     ///< Coulomb coefficient
  double kick = 0.0;         ///< speed added along the normal, units/s
  bool resting = false;      ///< slower than rest_speed: restitution 0 and no kick applied
  bool emitted = false;      ///< reported as a contact event (impact correction reads it)

  // Particle-particle velocity changes (kChange).
  int64_t pair = -1;  ///< index into DriftTape::pairs
  uint8_t side = 0;   ///< 0: the hit's particle i, 1: its particle j
};

/// One particle-particle contact of the pair schedule: the two discs move on linear tracks
/// x(tau) = xr + vc (tau - tr) from their last contact; the hit is at the root tau of
/// |x_i(tau) - x_j(tau)| = r_i + r_j (or at max(tr_i, tr_j) if they already overlap there),
/// with the impulse J = -(1 + e) vn / (w_i + w_j) along the normal n = (x_i - x_j) / |...|.
struct PairHit {
  uint32_t i = 0, j = 0;
  double tau = 0.0;               ///< time into the drift, s
  Vec2 xr_i{0, 0}, vc_i{0, 0};    ///< disc i's track before the hit
  Vec2 xr_j{0, 0}, vc_j{0, 0};    ///< disc j's track before the hit
  double tr_i = 0.0, tr_j = 0.0;  ///< the tracks' reference times, s
  double radius_sum = 0.0;        ///< r_i + r_j
  double w_i = 0.0, w_j = 0.0;    ///< inverse masses
  double restitution = 1.0;       ///< the pair restitution
  bool touching = false;          ///< already overlapping at max(tr_i, tr_j): tau = that time
};

/// Where the drift was not differentiable or came close (docs/gradients.md).
struct Finding {
  enum class Kind : uint8_t {
    kCapHit,   ///< the march ran out of collisions or iterations (the particle was carried)
    kTouch,    ///< the path entered the contact band without approaching: a contact may begin
    kGrazing,  ///< an impulse with almost no normal speed: the time of impact is ill-defined
    kStepEnd,  ///< an impulse at the end of the step inside the band: the contact straddles
               ///< two steps
    kResting,  ///< a resting contact (restitution dropped below rest_speed, or an impulse
               ///< inside the band): differentiable while it lasts, not where it switches
    kOrder     ///< pair changes out of time order
  };
  Kind kind = Kind::kTouch;
  uint32_t particle = 0;
  int64_t obstacle = -1;  ///< or -1 (a pair, or none)
  double t = 0.0;         ///< absolute time, s
  double margin = 0.0;    ///< e.g. the normal speed of a grazing impact
};

/// One drift as the backend did it.
struct DriftTape {
  double t0 = 0.0;              ///< time at the start of the drift, s
  double h = 0.0;               ///< its duration, s
  Eigen::Matrix2Xd x_in, v_in;  ///< the state entering it
  Eigen::VectorXd inv_mass;     ///< pinned particles (0) do not move
  std::vector<Impact> impacts;  ///< grouped by particle (increasing), each in time order
  std::vector<PairHit> pairs;   ///< in the order the schedule handled them
  std::vector<Finding> findings;
};

}  // namespace pinsim::grad
