// The sdf backend's limit on the numbers it computes with (README: Limits).
#pragma once

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <pinsim/plugin.hpp>
#include <string>

namespace pinsim::sdf {

/// Every number of an obstacle or input (coordinates, lengths, angles, speeds, times),
/// every initial particle coordinate and every particle's travel in one step (|v_x| dt,
/// |v_y| dt) is at most this in magnitude. Squares of lengths (the grid's area, |p|^2)
/// then stay below 1e19, far from overflow, and a coordinate's rounding (2^-52 of 1e9 is
/// 1.2e-7) stays below the default contact band depth_min * march_tolerance = 1e-6, so
/// the march can stop in it.
inline constexpr double kMaxMagnitude = 1e9;

/// Whether velocity (vx, vy) travels beyond `limit` along an axis in dt (a NaN does): the
/// sdf backend refuses such a step (its too_fast(), and the pair contacts' sweep).
inline bool travels_beyond(double vx, double vy, double dt, double limit = kMaxMagnitude) {
  return !(std::abs(vx) * dt <= limit && std::abs(vy) * dt <= limit);
}

/// A number for messages, as printf's %.6g.
inline std::string num(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

/// Throws Error "ctx: path: N is beyond ..." at the first number under `j` (depth first, in
/// file order) whose magnitude exceeds kMaxMagnitude. `path` is j's JSON path; it is
/// extended in place on the way down (so each value costs its key, not the whole path) and
/// restored. Nesting is bounded by the parser.
inline void check_magnitudes(const nlohmann::json& j, std::string& path, const std::string& ctx) {
  const std::size_t len = path.size();
  if (j.is_number()) {
    const double x = j.get<double>();
    if (!(std::abs(x) <= kMaxMagnitude))
      throw Error(ctx + ": " + path + ": " + num(x) +
                  " is beyond the limit of 1e+09 in magnitude for obstacle and input numbers "
                  "(backends/sdf/README.md, Limits)");
  } else if (j.is_array()) {
    for (std::size_t i = 0; i < j.size(); ++i) {
      path += "[" + std::to_string(i) + "]";
      check_magnitudes(j[i], path, ctx);
      path.resize(len);
    }
  } else if (j.is_object()) {
    for (const auto& [k, v] : j.items()) {
      path += (len == 0 ? "" : ".") + k;
      check_magnitudes(v, path, ctx);
      path.resize(len);
    }
  }
}

}  // namespace pinsim::sdf
