// Checking scene parameter values against a plugin's declared table.
#pragma once

#include <pinsim/abi.h>

#include <nlohmann/json.hpp>
#include <string>

namespace pinsim {

/// Validates `given` (a JSON object, or null for none) against the plugin's parameter table
/// and returns the complete parameter object with defaults filled in. Throws SceneError with
/// messages like "scene.json: forces[2].params.k: must be > 0, got -5". `where` is the
/// location prefix, e.g. "scene.json: forces[2].params".
nlohmann::json validate_params(const pinsim_plugin& plugin, const nlohmann::json& given,
                               const std::string& where);

/// A human-readable table of the declared parameters, for `pinsim plugins NAME`.
std::string format_param_table(const pinsim_plugin& plugin);

}  // namespace pinsim
