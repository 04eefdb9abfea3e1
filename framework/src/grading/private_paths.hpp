// What the grader keeps to itself, checked where the sandbox has no mount namespace to
// hide it (the fallback): the rubric and its folder, the scenes its tests run, the plugins
// the grader loads itself (references, second opinions, the scenes' other plugins) and their
// folders, and the output folder. Each is tried as the sandbox's uid under a step's
// confinement; none may open.
#pragma once

#include <filesystem>
#include <string>

#include "grading/rubric.hpp"

namespace pinsim::grading {

/// "" when no private path is within the fallback sandbox's reach; else the paths it could
/// open, comma-separated, each with "(read)" or "(write)". Makes `out` the grader's alone
/// (mode 0700) first.
std::string exposed_private_paths(const Rubric& rubric, const std::filesystem::path& out);

}  // namespace pinsim::grading
