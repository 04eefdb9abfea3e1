// `pinsim replay`: one self-contained HTML file that plays a run (no network needed).
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "pictures/render_data.hpp"

namespace pinsim {

struct ReplayOptions {
  int width = 640;                   ///< canvas width, pixels
  std::optional<ViewBox> view;       ///< world rectangle; default: scene and run bounds
  double obstacle_fps = 30;          ///< how often moving obstacles are sampled, frames per s
  std::size_t max_samples = 400000;  ///< trajectory samples kept (evenly thinned beyond)
};

/// Writes the replay page of `run` (obstacles from `scene` if given). Returns the pixel
/// mapping of the canvas. Throws std::runtime_error.
PixelMap write_replay(const RunData& run, const Scene* scene, PluginLoader& loader,
                      const ReplayOptions& opt, const std::filesystem::path& out);

/// The page template (replay_template.html, embedded at build time).
extern const char* const kReplayTemplate;

}  // namespace pinsim
