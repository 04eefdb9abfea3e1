// Limits on the values of a scene, chosen so that what the framework computes from them
// (1/m, v², m v², k d², distances, energies summed over a million particles) stays a finite,
// normal double. Documented in README.md (Scenes) and configs/scene.schema.json.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/json_read.hpp"

namespace pinsim {

/// |x|, |y| of a particle's position and a radius, scene units. Squared distances stay
/// below 1e101 and k d² below 1e201 with the parameter limit.
inline constexpr double kMaxCoordinate = 1e50;
/// |vx|, |vy| of a particle's velocity, scene units/s: v² below 1e101, m v² below 1e151.
inline constexpr double kMaxSpeed = 1e50;
/// A particle's mass lies in [kMinMass, kMaxMass]: 1/m is finite and normal.
inline constexpr double kMinMass = 1e-50;
inline constexpr double kMaxMass = 1e50;
/// |value| of every real plugin parameter (stiffness, damping, G, ...).
inline constexpr double kMaxParamMagnitude = 1e100;

/// Particles in a scene: 1,000,000, or $PINSIM_MAX_PARTICLES (a positive integer).
std::size_t max_particles();
/// Throws at `at` unless `existing + adding` is within max_particles().
void check_particle_count(std::size_t existing, uint64_t adding, const Loc& at);

/// Throws at `at` unless m is within [kMinMass, kMaxMass].
void check_mass(double m, const Loc& at);
/// Throws at `at` unless both components are within kMaxCoordinate.
void check_position(const Eigen::Vector2d& x, const Loc& at);
/// Throws at `at` unless both components are within kMaxSpeed.
void check_velocity(const Eigen::Vector2d& v, const Loc& at);
/// Throws at `at` unless 0 <= r <= kMaxCoordinate.
void check_radius(double r, const Loc& at);

}  // namespace pinsim
