#include "pictures/comparison.hpp"

#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "core/instances.hpp"
#include "pictures/cairo_handles.hpp"
#include "pictures/render_data.hpp"
#include "pictures/render_field.hpp"

namespace pinsim {
namespace {

/// The flat colours (0xRRGGBB): few of them, so that the PNG compresses well.
constexpr uint32_t kBackground = 0xf7f4ec;
constexpr uint32_t kObstacle = 0x4a505c;
constexpr uint32_t kFailed = 0xc0102f;
constexpr uint32_t kCrossing = 0xa000b0;

void set_rgb(cairo_t* cr, uint32_t rgb) {
  cairo_set_source_rgb(cr, ((rgb >> 16) & 255) / 255.0, ((rgb >> 8) & 255) / 255.0,
                       (rgb & 255) / 255.0);
}

double extent(const ViewBox& v) { return std::max(v.x1 - v.x0, v.y1 - v.y0); }

/// The world rectangle. The whole table (the obstacles over their whole motion) with the
/// reference's paths and the other run's as far as they stay near those (a ball that flew
/// off to 1e300 must not shrink the table to a dot); but where the paths take less than half
/// of that (a short run in a long channel), only the paths with a margin of half their size
/// and at least five ball radii. Padded, then widened to the picture's aspect ratio.
ViewBox comparison_view(const PathComparison& c, const BackendInstance& table) {
  ViewBox all = inverted_view(), paths = inverted_view();
  const State s0 = c.scene.initial_state();
  if (table.has_outline()) {
    const pinsim_bounds b = table.outline(s0, 0.0).sweep;
    if (b.x0 <= b.x1 && b.y0 <= b.y1 && std::isfinite(b.x0) && std::isfinite(b.x1) &&
        std::isfinite(b.y0) && std::isfinite(b.y1)) {
      all.add(b.x0, b.y0);
      all.add(b.x1, b.y1);
    }
  }
  for (const auto& path : c.reference)
    for (const auto& p : path) paths.add(p.x(), p.y());
  all = united(all, paths);
  ViewBox near = all;
  near.pad(1.0);
  auto inside = [&](const Eigen::Vector2d& p) {
    return p.allFinite() && p.x() >= near.x0 && p.x() <= near.x1 && p.y() >= near.y0 &&
           p.y() <= near.y1;
  };
  for (const auto& path : c.mine)
    for (const auto& p : path)
      if (inside(p)) paths.add(p.x(), p.y());
  if (c.crossing && inside(c.crossing->at)) paths.add(c.crossing->at.x(), c.crossing->at.y());
  all = united(all, paths);
  double radius = 0.0;
  for (Eigen::Index i = 0; i < s0.radius.size(); ++i) radius = std::max(radius, s0.radius[i]);
  ViewBox v = all;
  if (paths.x1 >= paths.x0) {
    const double margin = std::max(0.5 * extent(paths), 5 * radius);
    ViewBox zoomed{paths.x0 - margin, paths.y0 - margin, paths.x1 + margin, paths.y1 + margin};
    if (extent(zoomed) > 0 && extent(zoomed) < 0.5 * extent(all)) v = zoomed;
  }
  if (!(v.x1 >= v.x0)) v = ViewBox{0, 0, 0, 0};  // nothing at all
  if (!(extent(v) > 0)) {
    // One point: a unit box around it.
    const double cx = 0.5 * (v.x0 + v.x1), cy = 0.5 * (v.y0 + v.y1);
    v = ViewBox{cx - 1, cy - 1, cx + 1, cy + 1};
  }
  v.pad(0.06);
  const double aspect = static_cast<double>(kComparisonWidth) / kComparisonHeight;
  const double w = v.x1 - v.x0, h = v.y1 - v.y0;
  if (w < aspect * h) {
    const double grow = 0.5 * (aspect * h - w);
    v.x0 -= grow;
    v.x1 += grow;
  } else {
    const double grow = 0.5 * (w / aspect - h);
    v.y0 -= grow;
    v.y1 += grow;
  }
  return v;
}

/// Fills the obstacles and returns how many pixels it filled: each pixel by the distance d
/// from its centre to the nearest solid, in pixels: whole within half a pixel (so that a wall
/// thinner than a pixel still shows as a line), fading out to 1.5 pixels.
int fill_table(cairo_surface_t* image, const PixelMap& map, const BackendInstance& table,
               double t) {
  int filled = 0;
  cairo_surface_flush(image);
  unsigned char* data = cairo_image_surface_get_data(image);
  const int stride = cairo_image_surface_get_stride(image);
  auto channel = [](uint32_t rgb, int shift) { return static_cast<double>((rgb >> shift) & 255); };
  for (int j = 0; j < map.height; ++j) {
    auto* row = reinterpret_cast<uint32_t*>(data + static_cast<std::ptrdiff_t>(j) * stride);
    const double y = map.wy(j + 0.5);
    for (int i = 0; i < map.width; ++i) {
      const double d = table.distance(map.wx(i + 0.5), y, t, nullptr) * map.scale;
      const double a = std::isfinite(d) ? std::clamp(1.5 - d, 0.0, 1.0) : 0.0;
      if (a == 0.0) continue;
      uint32_t px = 0xff000000u;
      for (const int shift : {16, 8, 0}) {
        const double v = a * channel(kObstacle, shift) + (1 - a) * channel(kBackground, shift);
        px |= static_cast<uint32_t>(std::lround(v)) << shift;
      }
      row[i] = px;
      ++filled;
    }
  }
  cairo_surface_mark_dirty(image);
  return filled;
}

/// Clips the segment a-b (pixels) to a rectangle a little larger than the picture
/// (Liang-Barsky): cairo's fixed-point coordinates cannot take a ball that flew off to 1e300.
bool clip(double margin, const PixelMap& map, Eigen::Vector2d& a, Eigen::Vector2d& b) {
  if (!a.allFinite() || !b.allFinite()) return false;
  double t0 = 0.0, t1 = 1.0;
  const Eigen::Vector2d d = b - a;
  const double lo[2] = {-margin, -margin}, hi[2] = {map.width + margin, map.height + margin};
  for (int k = 0; k < 2; ++k) {
    for (const double sign : {-1.0, 1.0}) {
      const double p = sign * d[k];
      const double q = sign < 0 ? a[k] - lo[k] : hi[k] - a[k];
      if (p == 0.0) {
        if (q < 0) return false;
        continue;
      }
      const double r = q / p;
      if (p < 0)
        t0 = std::max(t0, r);
      else
        t1 = std::min(t1, r);
      if (t0 > t1) return false;
    }
  }
  const Eigen::Vector2d a0 = a;
  a = a0 + t0 * d;
  b = a0 + t1 * d;
  return true;
}

void draw_paths(cairo_t* cr, const PixelMap& map, const std::vector<PathComparison::Path>& paths,
                uint32_t rgb, double width) {
  cairo_save(cr);
  set_rgb(cr, rgb);
  cairo_set_line_width(cr, width);
  cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
  cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
  for (const auto& path : paths) {
    for (std::size_t s = 1; s < path.size(); ++s) {
      Eigen::Vector2d a(map.px(path[s - 1].x()), map.py(path[s - 1].y()));
      Eigen::Vector2d b(map.px(path[s].x()), map.py(path[s].y()));
      if (!clip(8.0, map, a, b)) continue;
      cairo_move_to(cr, a.x(), a.y());
      cairo_line_to(cr, b.x(), b.y());
    }
    cairo_stroke(cr);
    // The start: a dot.
    if (!path.empty() && path[0].allFinite()) {
      const double x = map.px(path[0].x()), y = map.py(path[0].y());
      if (x > -8 && x < map.width + 8 && y > -8 && y < map.height + 8) {
        cairo_new_sub_path(cr);
        cairo_arc(cr, x, y, width + 1.5, 0, 2 * M_PI);
        cairo_fill(cr);
      }
    }
  }
  cairo_restore(cr);
}

/// A mark at world point p if it is in the picture; `ring` true: a ring, else a cross.
void mark(cairo_t* cr, const PixelMap& map, const Eigen::Vector2d& p, uint32_t rgb, bool ring) {
  if (!p.allFinite()) return;
  const double x = map.px(p.x()), y = map.py(p.y());
  if (!(x > -10 && x < map.width + 10 && y > -10 && y < map.height + 10)) return;
  cairo_save(cr);
  set_rgb(cr, rgb);
  cairo_set_line_width(cr, 2.0);
  if (ring) {
    cairo_new_sub_path(cr);
    cairo_arc(cr, x, y, 7.0, 0, 2 * M_PI);
  } else {
    cairo_move_to(cr, x - 6, y - 6);
    cairo_line_to(cr, x + 6, y + 6);
    cairo_move_to(cr, x - 6, y + 6);
    cairo_line_to(cr, x + 6, y - 6);
  }
  cairo_stroke(cr);
  cairo_restore(cr);
}

}  // namespace

ComparisonPicture comparison_png(const PathComparison& c, PluginLoader& loader) {
  // The table: the scene's backend (the reference's), at the failing time.
  const std::unique_ptr<BackendInstance> table =
      make_backend(c.scene, loader, c.scene.backend_scene);
  PixelMap map;
  map.view = comparison_view(c, *table);
  map.width = kComparisonWidth;
  map.height = kComparisonHeight;
  map.scale = kComparisonWidth / (map.view.x1 - map.view.x0);

  CairoSurface surface(
      cairo_image_surface_create(CAIRO_FORMAT_RGB24, kComparisonWidth, kComparisonHeight));
  if (cairo_surface_status(surface.get()) != CAIRO_STATUS_SUCCESS)
    throw std::runtime_error("cairo: cannot make the comparison picture");
  {
    CairoContext ctx = cairo_context(surface.get());
    set_rgb(ctx.get(), kBackground);
    cairo_paint(ctx.get());
  }
  const int filled = table->has_distance() ? fill_table(surface.get(), map, *table, c.t) : 0;
  CairoContext ctx = cairo_context(surface.get());
  cairo_t* cr = ctx.get();
  // The reference's paths wide, the other's narrow on top: where they agree the blue shows
  // as a border of the orange.
  draw_paths(cr, map, c.reference, kComparisonReferenceRgb, 3.0);
  draw_paths(cr, map, c.mine, kComparisonMineRgb, 1.5);
  // Where the test failed: a ring on the other run's particle and a line to the reference's.
  {
    Eigen::Vector2d a(map.px(c.mine_at.x()), map.py(c.mine_at.y())),
        b(map.px(c.reference_at.x()), map.py(c.reference_at.y()));
    if (clip(8.0, map, a, b)) {
      cairo_save(cr);
      set_rgb(cr, kFailed);
      cairo_set_line_width(cr, 1.0);
      cairo_move_to(cr, a.x(), a.y());
      cairo_line_to(cr, b.x(), b.y());
      cairo_stroke(cr);
      cairo_restore(cr);
    }
  }
  mark(cr, map, c.mine_at, kFailed, true);
  if (c.crossing) mark(cr, map, c.crossing->at, kCrossing, false);
  ctx.reset();

  ComparisonPicture out;
  out.png = png_bytes(surface.get());
  if (out.png.empty()) throw std::runtime_error("cairo: cannot encode the comparison picture");
  out.width = kComparisonWidth;
  out.height = kComparisonHeight;
  out.legend =
      "Blue: the reference's path; orange: yours (a dot at each start); red ring: your ball "
      "at the step named below";
  out.legend += c.crossing ? "; purple cross: where a ball went into an obstacle." : ".";
  if (filled > 0) out.legend += " Obstacles are grey.";
  return out;
}

}  // namespace pinsim
