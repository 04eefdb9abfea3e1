// Small pieces shared by the subcommands.
#pragma once

#include <string>
#include <vector>

#include "core/scene.hpp"
#include "pictures/render_data.hpp"

namespace pinsim::cli {

/// Name of the scene compiled into the program (used when `run` gets no scene file).
extern const char* const kDefaultSceneName;
/// Its text.
extern const char* const kDefaultSceneText;

/// Loads the scene file, or the embedded default scene when `file` is empty.
Scene load_scene_or_default(const std::string& file, const std::vector<std::string>& overrides);

/// The overrides for `--backend NAME` followed by `--set` ones: the scene's backend becomes
/// NAME with the scene's own `crosscheck.params.NAME` when it has them (else NAME's
/// defaults), logged; the user's overrides apply after, so `--set backend.params.k=v`
/// sets the chosen backend's parameters. Unchanged when NAME is empty or the scene's own.
std::vector<std::string> with_backend(const std::string& file, const std::string& backend,
                                      const std::vector<std::string>& overrides);

/// The run in folder `dir`, for render and replay; InputError naming the folder if it is
/// not a run folder (no trajectory.csv) or one of its files cannot be read.
RunData read_run_folder(const std::filesystem::path& dir);

/// The world rectangle of `--view x0,y0,x1,y1`; InputError naming the flag otherwise.
ViewBox view_option(const std::string& text);

}  // namespace pinsim::cli
