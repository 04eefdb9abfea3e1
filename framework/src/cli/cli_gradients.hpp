// Pieces shared by `pinsim grad` and `pinsim fit`: losses from their specifications, a run
// folder's frames for a misfit, the scene with values set.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "gradients/losses.hpp"
#include "gradients/scene_gradient.hpp"

namespace pinsim::cli {

/// A run folder's recorded positions as frames at the steps of a run with time step dt
/// (`pinsim run --out` writes every output.every steps and the last); InputError naming the
/// folder if a frame's time is not a step time.
grad::RecordedFrames recorded_frames(const std::filesystem::path& dir, double dt);

/// The loss `spec` names (final:..., target:..., misfit:RUN_FOLDER), made for the run.
grad::LossFactory loss_factory(const std::string& spec);

/// The --set assignment that gives a resolved value these components ("path=1.5",
/// "path=[1,2]").
std::string assignment(const std::string& path, const std::vector<double>& value);

}  // namespace pinsim::cli
