// pinsim/transform.hpp: a 2D rotation and a rigid transform, shared by the backends and the
// host (Box2D's b2Rot / b2Transform in one header).
//
// Each operation is written out in one fixed order of floating-point operations, so that
// every caller gets the same bits (the build has -ffp-contract=off: no fused multiply-add):
//   R v       = (c x - s y, s x + c y)
//   R^T v     = (c x + s y, -s x + c y)
//   T p       = (c x - s y + tx, s x + c y + ty)
//   T^-1 p    = R^T (p - t)
//   A ∘ B     = (R_A R_B, A(t_B)), with R_A R_B = (cA cB - sA sB, sA cB + cA sB)
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace pinsim {

/// A rotation by an angle, kept as its cosine c and sine s.
struct Rotation {
  double c = 1.0;  ///< cos(angle)
  double s = 0.0;  ///< sin(angle)

  /// The rotation by `angle`, rad: (std::cos(angle), std::sin(angle)).
  static Rotation from_angle(double angle) { return {std::cos(angle), std::sin(angle)}; }
  /// R v.
  Eigen::Vector2d apply(const Eigen::Vector2d& v) const {
    return {c * v.x() - s * v.y(), s * v.x() + c * v.y()};
  }
  /// R^T v (the rotation by minus the angle).
  Eigen::Vector2d apply_inverse(const Eigen::Vector2d& v) const {
    return {c * v.x() + s * v.y(), -s * v.x() + c * v.y()};
  }
};

/// A rigid transform p -> R p + t (rotate, then translate).
struct Transform {
  Rotation r;                   ///< rotation
  Eigen::Vector2d t{0.0, 0.0};  ///< translation, scene units

  /// R p + t.
  Eigen::Vector2d apply(const Eigen::Vector2d& p) const {
    return {r.c * p.x() - r.s * p.y() + t.x(), r.s * p.x() + r.c * p.y() + t.y()};
  }
  /// R^T (p - t): the point of this frame that apply() maps to p.
  Eigen::Vector2d apply_inverse(const Eigen::Vector2d& p) const { return r.apply_inverse(p - t); }
  /// this ∘ inner: applies `inner` first, then this.
  Transform compose(const Transform& inner) const {
    return {{r.c * inner.r.c - r.s * inner.r.s, r.s * inner.r.c + r.c * inner.r.s}, apply(inner.t)};
  }
};

}  // namespace pinsim
