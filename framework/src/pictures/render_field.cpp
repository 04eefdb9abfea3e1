#include "pictures/render_field.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/instances.hpp"
#include "pictures/cairo_handles.hpp"

namespace pinsim {
using nlohmann::json;

FieldGrid sample_field(const DistanceFn& f, const PixelMap& map, int step) {
  FieldGrid g;
  g.step = std::max(step, 1);
  g.nx = (map.width + g.step - 1) / g.step;
  g.ny = (map.height + g.step - 1) / g.step;
  g.d.resize(static_cast<std::size_t>(g.nx) * g.ny);
  for (int j = 0; j < g.ny; ++j) {
    const double y = map.wy((j + 0.5) * g.step);
    for (int i = 0; i < g.nx; ++i)
      g.d[static_cast<std::size_t>(j) * g.nx + i] = f(map.wx((i + 0.5) * g.step), y);
  }
  return g;
}

std::vector<Segment> contour(const FieldGrid& g, double level) {
  std::vector<Segment> out;
  const double s = g.step;
  for (int j = 0; j + 1 < g.ny; ++j)
    for (int i = 0; i + 1 < g.nx; ++i) {
      // corners counter-clockwise in the grid: (i,j) (i+1,j) (i+1,j+1) (i,j+1)
      const int ci[4] = {i, i + 1, i + 1, i};
      const int cj[4] = {j, j, j + 1, j + 1};
      double v[4];
      bool finite = true;
      for (int k = 0; k < 4; ++k) {
        v[k] = g.at(ci[k], cj[k]) - level;
        finite = finite && std::isfinite(v[k]);
      }
      if (!finite) continue;
      double ex[4], ey[4];
      int n = 0;
      for (int k = 0; k < 4; ++k) {
        const int l = (k + 1) % 4;
        if ((v[k] < 0) == (v[l] < 0)) continue;
        const double w = v[k] / (v[k] - v[l]);
        ex[n] = ((ci[k] + w * (ci[l] - ci[k])) + 0.5) * s;
        ey[n] = ((cj[k] + w * (cj[l] - cj[k])) + 0.5) * s;
        ++n;
      }
      if (n == 2) {
        out.push_back({ex[0], ey[0], ex[1], ey[1]});
      } else if (n == 4) {
        // Saddle: the centre's sign decides which corners connect.
        const double c = 0.25 * (v[0] + v[1] + v[2] + v[3]);
        if ((c < 0) == (v[0] < 0)) {
          out.push_back({ex[0], ey[0], ex[1], ey[1]});
          out.push_back({ex[2], ey[2], ex[3], ey[3]});
        } else {
          out.push_back({ex[3], ey[3], ex[0], ey[0]});
          out.push_back({ex[1], ey[1], ex[2], ey[2]});
        }
      }
    }
  return out;
}

double contour_spacing(const ViewBox& view, int n) {
  const double raw = std::max(view.x1 - view.x0, view.y1 - view.y0) / std::max(n, 1);
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0})
    if (m * p >= raw) return m * p;
  return 10 * p;
}

namespace {

/// Colour of the field at distance d: dark inside, light outside, darker near surfaces.
void shade(double d, double spacing, double rgb[3]) {
  if (!std::isfinite(d)) {
    rgb[0] = 0.97, rgb[1] = 0.95, rgb[2] = 0.90;
    return;
  }
  if (d < 0) {
    const double k = 0.78 + 0.22 * std::exp(d / (3 * spacing));
    rgb[0] = 0.22 * k, rgb[1] = 0.27 * k, rgb[2] = 0.36 * k;
    return;
  }
  const double near = std::exp(-d / (2.5 * spacing));
  const double band = 0.025 * std::cos(2 * M_PI * d / spacing);
  rgb[0] = 0.97 - 0.10 * near + band;
  rgb[1] = 0.95 - 0.22 * near + band;
  rgb[2] = 0.90 - 0.35 * near + band;
}

uint32_t argb(double a, double r, double g, double b) {
  auto c = [](double v) {
    return static_cast<uint32_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255));
  };
  return (c(a) << 24) | (c(r * a) << 16) | (c(g * a) << 8) | c(b * a);  // premultiplied
}

void stroke_segments(cairo_t* cr, const std::vector<Segment>& segs) {
  for (const auto& s : segs) {
    cairo_move_to(cr, s.x0, s.y0);
    cairo_line_to(cr, s.x1, s.y1);
  }
  cairo_stroke(cr);
}

/// Paints an image of g's samples, one image pixel per sample, scaled to pixels; the
/// sample (i, j) has the premultiplied ARGB colour pixel(i, j).
template <class PixelFn>
void paint_samples(cairo_t* cr, const FieldGrid& g, PixelFn pixel) {
  const CairoSurface img = image_surface(g.nx, g.ny);
  cairo_surface_flush(img.get());
  unsigned char* data = cairo_image_surface_get_data(img.get());
  const int stride = cairo_image_surface_get_stride(img.get());
  for (int j = 0; j < g.ny; ++j) {
    auto* row = reinterpret_cast<uint32_t*>(data + static_cast<std::ptrdiff_t>(j) * stride);
    for (int i = 0; i < g.nx; ++i) row[i] = pixel(i, j);
  }
  cairo_surface_mark_dirty(img.get());
  cairo_save(cr);
  cairo_scale(cr, g.step, g.step);
  cairo_set_source_surface(cr, img.get(), 0, 0);
  cairo_pattern_set_filter(cairo_get_source(cr),
                           g.step == 1 ? CAIRO_FILTER_NEAREST : CAIRO_FILTER_BILINEAR);
  cairo_paint(cr);
  cairo_restore(cr);
}

/// Strokes the surface (g's zero contour) in near black, `width` pixels wide.
void stroke_surface(cairo_t* cr, const FieldGrid& g, double width) {
  cairo_save(cr);
  cairo_set_source_rgb(cr, 0.05, 0.06, 0.10);
  cairo_set_line_width(cr, width);
  stroke_segments(cr, contour(g, 0.0));
  cairo_restore(cr);
}

}  // namespace

void draw_field(cairo_t* cr, const PixelMap& map, const FieldGrid& g, double spacing,
                bool contours) {
  const double world_per_sample = g.step / map.scale;
  paint_samples(cr, g, [&](int i, int j) {
    double c[3];
    const double d = g.at(i, j);
    shade(d, spacing, c);
    // Antialias the surface itself: blend the two sides over one sample.
    if (std::isfinite(d) && std::abs(d) < world_per_sample) {
      double in[3], out[3];
      shade(-1e-12, spacing, in);
      shade(1e-12, spacing, out);
      const double w = 0.5 + 0.5 * d / world_per_sample;
      for (int k = 0; k < 3; ++k) c[k] = w * out[k] + (1 - w) * in[k];
    }
    return argb(1, c[0], c[1], c[2]);
  });

  cairo_save(cr);
  cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
  if (contours) {
    double lo = HUGE_VAL, hi = -HUGE_VAL;
    for (const double d : g.d)
      if (std::isfinite(d)) lo = std::min(lo, d), hi = std::max(hi, d);
    if (lo < hi) {
      cairo_set_line_width(cr, 0.6);
      const int k0 = static_cast<int>(std::ceil(lo / spacing)),
                k1 = static_cast<int>(std::floor(hi / spacing));
      for (int k = std::max(k0, -200); k <= std::min(k1, 200); ++k) {
        if (k == 0) continue;
        if (k > 0)
          cairo_set_source_rgba(cr, 0.55, 0.42, 0.25, 0.55);
        else
          cairo_set_source_rgba(cr, 0.65, 0.72, 0.85, 0.45);
        stroke_segments(cr, contour(g, k * spacing));
      }
    }
  }
  stroke_surface(cr, g, 1.6);
  cairo_restore(cr);
}

void draw_solid(cairo_t* cr, const FieldGrid& g, double r, double gr, double b) {
  // Coverage from the distance in samples, estimated from the local gradient.
  paint_samples(cr, g, [&](int i, int j) {
    const double d = g.at(i, j);
    double a = d < 0 ? 1.0 : 0.0;
    if (std::isfinite(d) && i + 1 < g.nx && j + 1 < g.ny) {
      const double gx = g.at(i + 1, j) - d, gy = g.at(i, j + 1) - d;
      const double gn = std::hypot(gx, gy);
      if (gn > 0 && std::isfinite(gn)) a = std::clamp(0.5 - d / gn, 0.0, 1.0);
    }
    return argb(a, r, gr, b);
  });
  stroke_surface(cr, g, 1.4);
}

std::unique_ptr<BackendInstance> make_backend(const Scene& scene, PluginLoader& loader,
                                              const json& backend_scene) {
  return create_backend(scene, loader, scene.backend, backend_scene, scene.initial_state());
}

json static_obstacles(const json& backend_scene) {
  json out = backend_scene;
  if (!out.is_object()) return out;
  if (out.contains("obstacles")) {
    json keep = json::array();
    for (const auto& o : out["obstacles"])
      if (!o.contains("motion")) keep.push_back(o);
    out["obstacles"] = keep;
  }
  out.erase("inputs");
  return out;
}

json moving_obstacles(const json& backend_scene) {
  if (!backend_scene.is_object() || !backend_scene.contains("obstacles")) return nullptr;
  json out = backend_scene;
  json keep = json::array();
  for (const auto& o : out["obstacles"])
    if (o.contains("motion")) keep.push_back(o);
  if (keep.empty()) return nullptr;
  out["obstacles"] = keep;
  return out;
}

std::string png_bytes(cairo_surface_t* image) {
  std::string out;
  cairo_surface_write_to_png_stream(
      image,
      [](void* closure, const unsigned char* data, unsigned int n) {
        static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), n);
        return CAIRO_STATUS_SUCCESS;
      },
      &out);
  return out;
}

void draw_static_table(cairo_t* cr, const Scene& scene, PluginLoader& loader, const PixelMap& map) {
  auto be = make_backend(scene, loader, static_obstacles(scene.backend_scene));
  const FieldGrid g =
      sample_field([&](double x, double y) { return be->distance(x, y, 0.0, nullptr); }, map, 1);
  draw_field(cr, map, g, contour_spacing(map.view));
}

}  // namespace pinsim
