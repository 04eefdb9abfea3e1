// Small pieces shared by the subcommands.
#pragma once

#include <string>
#include <vector>

#include "core/scene.hpp"

namespace pinsim::cli {

/// Name of the scene compiled into the program (used when `run` gets no scene file).
extern const char* const kDefaultSceneName;
/// Its text.
extern const char* const kDefaultSceneText;

/// Loads the scene file, or the embedded default scene when `file` is empty.
Scene load_scene_or_default(const std::string& file, const std::vector<std::string>& overrides);

}  // namespace pinsim::cli
