// The distance field as a picture: sampling a backend's distance() on a pixel grid,
// contour lines by marching squares, and drawing both with cairo.
#pragma once

#include <cairo.h>

#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "core/plugin_instance.hpp"
#include "core/scene.hpp"
#include "pictures/render_data.hpp"

namespace pinsim {

/// Signed distance at a world point (negative inside an obstacle).
using DistanceFn = std::function<double(double x, double y)>;

/// Samples of a field at pixel positions ((i + 0.5) step, (j + 0.5) step), i < nx, j < ny.
struct FieldGrid {
  int nx = 0, ny = 0;
  double step = 1;  ///< pixels between samples
  std::vector<double> d;
  double at(int i, int j) const { return d[static_cast<std::size_t>(j) * nx + i]; }
};

/// Samples `f` over the whole map every `step` pixels (a sub-region: pass a PixelMap of it).
FieldGrid sample_field(const DistanceFn& f, const PixelMap& map, int step);

/// One line piece in pixel coordinates.
struct Segment {
  double x0, y0, x1, y1;
};

/// Marching squares: the pieces of the level set d = level (pixel coordinates).
std::vector<Segment> contour(const FieldGrid& g, double level);

/// A "nice" contour spacing (1, 2 or 5 times a power of ten) giving about `n` lines across
/// the view.
double contour_spacing(const ViewBox& view, int n = 24);

/// Draws the shaded field, thin contour lines every `spacing` and the zero contour sharp.
/// `image_step` is the resolution of the shading image in pixels (1 = every pixel).
void draw_field(cairo_t* cr, const PixelMap& map, const FieldGrid& g, double spacing,
                bool contours = true);

/// Fills where d < 0 (antialiased by distance) with colour (r, g, b) and strokes the zero
/// contour: for moving obstacles drawn over a static background.
void draw_solid(cairo_t* cr, const FieldGrid& g, double r, double gr, double b);

/// A backend instance for the scene's backend with a replaced obstacle description (e.g.
/// only the static or only the moving obstacles), made by core's create_backend.
std::unique_ptr<BackendInstance> make_backend(const Scene& scene, PluginLoader& loader,
                                              const nlohmann::json& backend_scene);

/// Draws the scene's static obstacles as a field (draw_field, spacing contour_spacing): the
/// table under the moving parts, as `play` and `share` show it.
void draw_static_table(cairo_t* cr, const Scene& scene, PluginLoader& loader, const PixelMap& map);

/// The scene's backend description without moving obstacles (and without inputs).
nlohmann::json static_obstacles(const nlohmann::json& backend_scene);
/// Only the moving obstacles, with the inputs; null if the scene has none.
nlohmann::json moving_obstacles(const nlohmann::json& backend_scene);

/// Writes a cairo image surface to PNG bytes in memory.
std::string png_bytes(cairo_surface_t* image);

}  // namespace pinsim
