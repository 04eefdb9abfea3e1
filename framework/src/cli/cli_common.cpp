#include "cli_common.hpp"

#include <filesystem>

namespace pinsim::cli {

Scene load_scene_or_default(const std::string& file, const std::vector<std::string>& overrides) {
  if (!file.empty()) return load_scene(file, overrides);
  return parse_scene(kDefaultSceneText, std::string("<embedded ") + kDefaultSceneName + ">",
                     std::filesystem::current_path(), overrides);
}

}  // namespace pinsim::cli
