#include "bodies.hpp"

#include "scene_error.hpp"

namespace pinsim {

std::vector<std::string> body_types() { return {}; }

Body build_body(const nlohmann::json& spec, const std::string& where, ParticleList&) {
  const std::string type = spec.value("type", std::string());
  throw SceneError(where + ".type: unknown body type '" + type + "'");
}

}  // namespace pinsim
