// ContactOptions: the scene's "contacts" block, read by every backend with particle-particle
// contacts (sdf, box2d) through this one parser, so both accept the same values and give the
// same errors.
#pragma once

#include <pinsim/plugin.hpp>
#include <pinsim/scene_field/json_in.hpp>
#include <string>

namespace pinsim::sdf {

/// "contacts": {"particles": true|false, "restitution": number in [0, 1]}.
struct ContactOptions {
  bool particles = false;    ///< particle-particle contacts on
  double restitution = 1.0;  ///< their restitution (1: elastic)
};

/// The "contacts" object of a backend's scene (`ctx.scene`); the defaults if it is absent
/// or null. Throws pinsim::Error "<file>: contacts.<key>: <what was expected>".
inline ContactOptions read_contacts(const CreateContext& ctx) {
  ContactOptions out;
  const JsonIn scene(ctx.scene, "", ctx.context);
  if (!ctx.scene.is_object() || !scene.has("contacts")) return out;
  const JsonIn c = scene.object("contacts");
  c.only({"particles", "restitution"});
  out.particles = c.boolean("particles", false);
  out.restitution = c.number_if(
      "restitution", 1.0, [](double x) { return x >= 0.0 && x <= 1.0; }, "must be in [0, 1]");
  return out;
}

}  // namespace pinsim::sdf
