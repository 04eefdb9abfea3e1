#include "tools/bench_answer.hpp"

#include <cmath>

#include "core/input_error.hpp"

namespace pinsim::bench {
namespace {

Eigen::Vector2d vec(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.contains(key) || !j[key].is_array() || j[key].size() != 2 || !j[key][0].is_number() ||
      !j[key][1].is_number())
    throw InputError(where + "." + key + ": expected [x, y] (two numbers)");
  return {j[key][0].get<double>(), j[key][1].get<double>()};
}

double number(const nlohmann::json& j, const char* key, double def, const std::string& where) {
  if (!j.contains(key)) {
    if (std::isnan(def)) throw InputError(where + "." + key + ": required number is missing");
    return def;
  }
  if (!j[key].is_number()) throw InputError(where + "." + key + ": expected a number");
  return j[key].get<double>();
}

// u folded into [a, b] by mirror reflections (period 2 (b - a)).
double fold(double u, double a, double b) {
  const double L = b - a;
  double s = std::fmod(u - a, 2.0 * L);
  if (s < 0) s += 2.0 * L;
  return s <= L ? a + s : b - (s - L);
}

}  // namespace

Answer::Answer(const nlohmann::json& spec, const State& s, const std::string& where) {
  if (!spec.is_object() || !spec.contains("type") || !spec["type"].is_string())
    throw InputError(where + ".type: expected projectile, harmonic, bouncing_ball or ball_in_box");
  type_ = spec["type"].get<std::string>();
  const double pi = number(spec, "particle", 0.0, where);
  if (pi < 0 || static_cast<std::size_t>(pi) >= s.size())
    throw InputError(where + ".particle: no particle " + std::to_string(pi));
  p_ = static_cast<std::size_t>(pi);
  const auto ip = static_cast<Eigen::Index>(p_);
  x0_ = s.x.col(ip);
  v0_ = s.v.col(ip);
  r_ = s.radius[ip];
  if (type_ == "projectile") {
    g_ = vec(spec, "g", where);
  } else if (type_ == "harmonic") {
    w_ = number(spec, "omega", NAN, where);
    z_ = number(spec, "damping_ratio", 0.0, where);
    if (!(w_ > 0) || !(z_ >= 0 && z_ < 1))
      throw InputError(where + ": need omega > 0 and 0 <= damping_ratio < 1");
    c_ = spec.contains("center") ? vec(spec, "center", where) : Eigen::Vector2d::Zero();
  } else if (type_ == "bouncing_ball") {
    floor_ = number(spec, "floor", 0.0, where);
    gs_ = number(spec, "g", 9.81, where);
    e_ = number(spec, "restitution", 1.0, where);
    if (!(gs_ > 0) || !(e_ > 0 && e_ <= 1))
      throw InputError(where + ": need g > 0 and 0 < restitution <= 1");
  } else if (type_ == "ball_in_box") {
    lo_ = vec(spec, "min", where) + Eigen::Vector2d::Constant(r_);
    hi_ = vec(spec, "max", where) - Eigen::Vector2d::Constant(r_);
    if (!(hi_.array() > lo_.array()).all())
      throw InputError(where + ": the box is smaller than the ball");
  } else {
    throw InputError(where + ".type: unknown answer '" + type_ +
                     "' (known: projectile, harmonic, bouncing_ball, ball_in_box; or give "
                     "\"reference\" for a fine reference run)");
  }
}

Eigen::Vector2d Answer::position(double t) const {
  if (type_ == "projectile") return x0_ + v0_ * t + 0.5 * g_ * t * t;
  if (type_ == "harmonic") {
    const double wd = w_ * std::sqrt(1.0 - z_ * z_);
    const Eigen::Vector2d A = x0_ - c_, B = (v0_ + z_ * w_ * A) / wd;
    return c_ + std::exp(-z_ * w_ * t) * (A * std::cos(wd * t) + B * std::sin(wd * t));
  }
  if (type_ == "bouncing_ball") {
    // Walk the impacts: from (y, vy) at ta the next contact y = yc is after
    // s = (vy + sqrt(vy^2 + 2 g (y - yc))) / g.
    const double yc = floor_ + r_;
    double ta = 0.0, y = x0_.y(), vy = v0_.y();
    for (int k = 0; k < 100000; ++k) {
      const double s = (vy + std::sqrt(std::max(0.0, vy * vy + 2.0 * gs_ * (y - yc)))) / gs_;
      if (t <= ta + s || !(s > 0.0)) {
        const double u = t - ta;
        return {x0_.x() + v0_.x() * t, y + vy * u - 0.5 * gs_ * u * u};
      }
      ta += s;
      vy = -e_ * (vy - gs_ * s);
      y = yc;
    }
    return {x0_.x() + v0_.x() * t, yc};
  }
  // ball_in_box
  const Eigen::Vector2d u = x0_ + v0_ * t;
  return {fold(u.x(), lo_.x(), hi_.x()), fold(u.y(), lo_.y(), hi_.y())};
}

}  // namespace pinsim::bench
