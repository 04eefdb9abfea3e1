// Closed-form answers for bench scenes: the position of one particle at time t.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <pinsim/state.hpp>
#include <string>

namespace pinsim::bench {

/// One of:
///  {"type": "projectile", "particle": i, "g": [gx, gy]}:  x0 + v0 t + g t^2 / 2
///  {"type": "harmonic", "particle": i, "omega": w, "center": [cx, cy], "damping_ratio": z}
///     x = c + e^{-z w t} (A cos(wd t) + B sin(wd t)), wd = w sqrt(1 - z^2), A = x0 - c,
///     B = (v0 + z w A) / wd  (z < 1; z = 0 default: undamped)
///  {"type": "bouncing_ball", "particle": i, "floor": y_f, "g": g, "restitution": e}
///     parabolas y = y_a + vy_a s - g s^2/2 between impacts at y = y_f + r, where
///     vy -> -e vy; x = x0 + vx t
///  {"type": "ball_in_box", "particle": i, "min": [x, y], "max": [x, y]}: no force, walls
///     of the box interior, e = 1: each coordinate x0 + v0 t folded into [min + r, max - r]
class Answer {
 public:
  Answer(const nlohmann::json& spec, const State& initial, const std::string& where);
  Eigen::Vector2d position(double t) const;
  std::size_t particle() const { return p_; }

 private:
  std::string type_;
  std::size_t p_ = 0;
  Eigen::Vector2d x0_, v0_, g_, c_, lo_, hi_;
  double w_ = 0, z_ = 0, floor_ = 0, gs_ = 0, e_ = 1, r_ = 0;
};

}  // namespace pinsim::bench
