// `pinsim render`: a picture of a scene or of runs (PNG or SVG, drawn with cairo).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "pictures/render_data.hpp"

namespace pinsim {

struct RenderOptions {
  int width = 900;              ///< picture width, pixels (the height follows the view)
  std::optional<ViewBox> view;  ///< world rectangle; default: the scene and runs' bounds
  std::optional<double> time;   ///< time of obstacles and particles; default 0 / run end
  bool field = true;            ///< shade the distance field and draw contour lines
  bool trajectories = true;     ///< draw the runs' paths
  bool contacts = true;         ///< mark the runs' contacts
  std::string title;            ///< text at the top left; default: scene name and time
};

/// What a picture shows: a scene (obstacles, particles, springs) and any number of runs
/// overlaid (one: its particles' paths; several, e.g. a crosscheck: one colour per run).
struct RenderJob {
  std::optional<Scene> scene;
  std::vector<RunData> runs;
};

/// Draws the picture into `out`: PNG or SVG by its extension. Returns the pixel mapping
/// (so callers and tests know where a world point landed). Throws std::runtime_error.
PixelMap render_picture(const RenderJob& job, PluginLoader& loader, const RenderOptions& opt,
                        const std::filesystem::path& out);

/// RGB colour of run k's particle i as drawn (the first run's particle 0 is red).
void particle_colour(std::size_t run, std::size_t particle, double rgb[3]);

}  // namespace pinsim
