// What Box2D 2.4.1 asserts (b2Assert aborts the process) or silently degrades on, checked
// before it is called: coordinates within float's useful range, polygons that its
// b2PolygonShape::Set accepts, chain vertices apart, masses and inertias that are normal
// floats. Each check returns "" or what is wrong, for an error naming the JSON path.
#pragma once

#include <box2d/box2d.h>

#include <pinsim/plugin.hpp>
#include <string>
#include <vector>

namespace pinsim::box2d {

/// Largest |coordinate| in Box2D units (a body's position, a shape's vertex in its body's
/// frame, a radius). A float's rounding there (2^-24 of 1e4 is 6e-4) stays below an eighth
/// of b2_linearSlop (0.005), the scale of Box2D's contact tolerances.
inline constexpr double kMaxUnits = 1e4;
/// Masses, densities and rotational inertias handed to Box2D lie in [1/kMaxFloatValue,
/// kMaxFloatValue]: normal floats with room for the solver's products.
inline constexpr double kMaxFloatValue = 1e30;

/// "" if |x|, |y| <= kMaxUnits, else what is wrong ("(x, y) is beyond ...").
std::string coordinate_problem(double x, double y);
/// What b2PolygonShape::Set would assert on for these vertices, in its own float arithmetic
/// (count in [3, b2_maxPolygonVertices], at least 3 vertices after welding within
/// b2_linearSlop / 2, a gift-wrapped hull of at least 3 vertices, edges longer than
/// b2_epsilon, area above b2_epsilon), or "".
std::string polygon_problem(const b2Vec2* v, int count);
/// What b2ChainShape::CreateLoop / CreateChain would assert on (at least 3 / 2 vertices,
/// consecutive vertices, and the loop's last and first, farther apart than b2_linearSlop),
/// or "".
std::string chain_problem(const std::vector<b2Vec2>& v, bool loop);
/// A dynamic circle body of mass m (scene units; Box2D gets density m / (pi (r s)^2)) and
/// Box2D radius rs: "" if the density, the mass and (when it rotates) the inertia
/// m (rs)^2 / 2 are normal floats within kMaxFloatValue.
std::string particle_mass_problem(double m, double rs, bool rotates);

}  // namespace pinsim::box2d
