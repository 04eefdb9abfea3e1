// pinsim/state.hpp: the particle state, plain data that can be copied, compared and hashed.
#pragma once

#include <pinsim/abi.h>

#include <Eigen/Core>
#include <cstdint>
#include <cstring>

namespace pinsim {

/// State {t, x (2xN), v (2xN), inv_mass, radius}. Columns are particles.
struct State {
  double t = 0.0;            ///< time, s
  Eigen::Matrix2Xd x;        ///< positions, scene units
  Eigen::Matrix2Xd v;        ///< velocities, units/s
  Eigen::VectorXd inv_mass;  ///< 1/mass per particle, 1/kg; 0 = pinned
  Eigen::VectorXd radius;    ///< radius per particle, scene units

  std::size_t size() const { return static_cast<std::size_t>(x.cols()); }

  /// Read-only C view for plugins.
  pinsim_state_view view() const {
    return {static_cast<uint64_t>(size()), t, x.data(), v.data(), inv_mass.data(), radius.data()};
  }
  /// Mutable C view for a backend's advance().
  pinsim_state_mut mut() {
    return {static_cast<uint64_t>(size()), t, x.data(), v.data(), inv_mass.data(), radius.data()};
  }

  /// FNV-1a 64-bit hash of the bytes of t, x and v: equal hashes mean bit-identical states.
  uint64_t hash() const {
    uint64_t h = 1469598103934665603ull;
    auto mix = [&h](const void* p, std::size_t n) {
      const auto* b = static_cast<const unsigned char*>(p);
      for (std::size_t i = 0; i < n; ++i) {
        h ^= b[i];
        h *= 1099511628211ull;
      }
    };
    mix(&t, sizeof t);
    mix(x.data(), sizeof(double) * static_cast<std::size_t>(x.size()));
    mix(v.data(), sizeof(double) * static_cast<std::size_t>(v.size()));
    return h;
  }
};

}  // namespace pinsim
