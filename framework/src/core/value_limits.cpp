#include "core/value_limits.hpp"

#include <cmath>
#include <cstdlib>

#include "core/format.hpp"

namespace pinsim {
namespace {

/// The shortest text that reads back as x ("1e-320", not 9.99989e-321).
std::string exact(double x) {
  for (int digits = 1; digits < 17; ++digits) {
    const std::string t = num(x, digits);
    if (std::strtod(t.c_str(), nullptr) == x) return t;
  }
  return num(x, 17);
}

void check_components(const Eigen::Vector2d& x, double limit, const Loc& at, const char* what) {
  for (int i = 0; i < 2; ++i)
    if (!(std::abs(x[i]) <= limit))
      at[static_cast<std::size_t>(i)].fail(
          std::string(what) + " " + exact(x[i]) + " is beyond the limit of " + num(limit) +
          " in magnitude (so that squares and energies stay finite)");
}

}  // namespace

std::size_t max_particles() {
  const char* v = std::getenv("PINSIM_MAX_PARTICLES");
  if (v == nullptr || *v == '\0') return 1'000'000;
  const std::string text = v;
  if (text.size() > 12 || text.find_first_not_of("0123456789") != std::string::npos ||
      std::stoull(text) == 0)
    throw SceneError("$PINSIM_MAX_PARTICLES=" + text +
                     ": expected a positive integer (at most 12 digits)");
  return std::stoull(text);
}

void check_particle_count(std::size_t existing, uint64_t adding, const Loc& at) {
  const std::size_t limit = max_particles();
  if (adding > limit || existing > limit - adding)
    at.fail(std::to_string(adding) + " particles here make " + std::to_string(existing + adding) +
            ", more than the limit of " + std::to_string(limit) +
            " particles in a scene ($PINSIM_MAX_PARTICLES raises it)");
}

void check_mass(double m, const Loc& at) {
  if (!(m >= kMinMass && m <= kMaxMass))
    at.fail("must be between " + num(kMinMass) + " and " + num(kMaxMass) +
            " (so that 1/m and m v^2 stay finite), got " + exact(m));
}

void check_position(const Eigen::Vector2d& x, const Loc& at) {
  check_components(x, kMaxCoordinate, at, "coordinate");
}

void check_velocity(const Eigen::Vector2d& v, const Loc& at) {
  check_components(v, kMaxSpeed, at, "velocity");
}

void check_radius(double r, const Loc& at) {
  if (!(r >= 0.0 && r <= kMaxCoordinate))
    at.fail("must be between 0 and " + num(kMaxCoordinate) + ", got " + exact(r));
}

}  // namespace pinsim
