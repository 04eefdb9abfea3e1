#include "pictures/replay.hpp"

#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/base64.hpp"
#include "core/output_file.hpp"
#include "core/simulation.hpp"
#include "pictures/cairo_handles.hpp"
#include "pictures/render.hpp"
#include "pictures/render_field.hpp"

namespace pinsim {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

double round2(double v) { return std::round(v * 100.0) / 100.0; }

std::string hex_colour(const double c[3]) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", static_cast<int>(std::lround(c[0] * 255)),
                static_cast<int>(std::lround(c[1] * 255)),
                static_cast<int>(std::lround(c[2] * 255)));
  return buf;
}

/// The zero contour of the moving obstacles at sampled times, in canvas pixels.
json moving_frames(const BackendInstance& moving, const State& initial, const PixelMap& map,
                   double t_end, double fps) {
  ViewBox region = obstacles_view(moving, initial);
  if (region.empty()) return nullptr;
  region.pad(0.02);
  // The sub-grid shares the canvas scale and is aligned to its pixels.
  const double px0 = std::floor(std::max(0.0, map.px(region.x0)));
  const double py0 = std::floor(std::max(0.0, map.py(region.y1)));
  const double px1 = std::ceil(std::min<double>(map.width, map.px(region.x1)));
  const double py1 = std::ceil(std::min<double>(map.height, map.py(region.y0)));
  if (!(px1 > px0 && py1 > py0)) return nullptr;
  PixelMap sub;
  sub.scale = map.scale;
  sub.width = static_cast<int>(px1 - px0);
  sub.height = static_cast<int>(py1 - py0);
  sub.view = ViewBox{map.wx(px0), map.wy(py1), map.wx(px1), map.wy(py0)};
  const int step = sub.width * sub.height > 120000 ? 3 : 2;
  const int n = std::clamp(static_cast<int>(std::ceil(t_end * fps)) + 1, 1, 2000);
  json times = json::array(), frames = json::array();
  for (int k = 0; k < n; ++k) {
    const double t = n == 1 ? 0.0 : t_end * k / (n - 1);
    const FieldGrid g = sample_field(
        [&](double x, double y) { return moving.distance(x, y, t, nullptr); }, sub, step);
    json segs = json::array();
    for (const Segment& s : contour(g, 0.0))
      for (const double v : {s.x0 + px0, s.y0 + py0, s.x1 + px0, s.y1 + py0})
        segs.push_back(round2(v));
    times.push_back(t);
    frames.push_back(std::move(segs));
  }
  return {{"times", times}, {"frames", frames}};
}

/// The scene's obstacles as the page draws them: `fixed` the static ones (all of them if
/// none moves), drawn once as the background; `moving` the moving ones, drawn per frame
/// (null if none moves). Both null without a scene.
struct ObstacleBackends {
  std::unique_ptr<BackendInstance> fixed, moving;
};

ObstacleBackends obstacle_backends(const Scene* scene, PluginLoader& loader) {
  ObstacleBackends b;
  if (!scene) return b;
  const json mov = moving_obstacles(scene->backend_scene);
  b.fixed =
      make_backend(*scene, loader,
                   mov.is_null() ? scene->backend_scene : static_obstacles(scene->backend_scene));
  if (!mov.is_null()) b.moving = make_backend(*scene, loader, mov);
  return b;
}

/// The world rectangle shown: the scene's and its obstacles' (padded without a scene) with
/// the run's path, unless the options give one.
ViewBox replay_view(const RunData& run, const Scene* scene, const ObstacleBackends& b,
                    const ReplayOptions& opt) {
  ViewBox view = inverted_view();
  if (scene) {
    const State s = scene->initial_state();
    ViewBox obstacles = obstacles_view(*b.fixed, s);
    if (b.moving) obstacles = united(obstacles, obstacles_view(*b.moving, s));
    view = scene_view(*scene, obstacles);
  }
  add_run_to_view(run, view, 0.0);
  if (view.empty()) view = ViewBox{};
  if (!scene) view.pad(0.05);
  if (opt.view) {
    check_view(*opt.view, view, opt.width);
    view = *opt.view;
  }
  return view;
}

/// The background as PNG bytes: the static obstacles' field (contour lines spaced for
/// `view`) on the paper colour.
std::string background_png(const ObstacleBackends& b, const PixelMap& map, const ViewBox& view) {
  const CairoSurface bg = image_surface(map.width, map.height);
  {
    const CairoContext cr = cairo_context(bg.get());
    cairo_set_source_rgb(cr.get(), 0.97, 0.95, 0.90);
    cairo_paint(cr.get());
    if (b.fixed && b.fixed->has_distance()) {
      const FieldGrid g = sample_field(
          [&](double x, double y) { return b.fixed->distance(x, y, 0.0, nullptr); }, map, 1);
      draw_field(cr.get(), map, g, contour_spacing(view));
    }
  }
  return png_bytes(bg.get());
}

/// The moving obstacles' frames (moving_frames) when they and the static ones have a
/// distance; null otherwise. `s0`: the scene's initial state.
json moving_json(const ObstacleBackends& b, const State* s0, const PixelMap& map, double t_end,
                 double fps) {
  if (!s0 || !b.fixed || !b.fixed->has_distance() || !b.moving || !b.moving->has_distance())
    return nullptr;
  return moving_frames(*b.moving, *s0, map, t_end, fps);
}

/// Each particle's path in canvas pixels, thinned evenly if there are too many samples, with
/// its colour and radius (from the scene's initial state `s0`, at least 2.5 pixels).
json particles_json(const RunData& run, const PixelMap& map, const State* s0,
                    std::size_t max_samples) {
  std::size_t total = 0;
  for (const auto& p : run.particles) total += p.size();
  const std::size_t stride = std::max<std::size_t>(1, (total + max_samples - 1) / max_samples);
  json particles = json::array();
  for (std::size_t i = 0; i < run.particles.size(); ++i) {
    const auto& p = run.particles[i];
    json t = json::array(), x = json::array(), y = json::array();
    for (std::size_t k = 0; k < p.size(); ++k) {
      if (k % stride != 0 && k + 1 != p.size()) continue;
      t.push_back(p[k].t);
      x.push_back(round2(map.px(p[k].x)));
      y.push_back(round2(map.py(p[k].y)));
    }
    double c[3];
    particle_colour(0, i, c);
    const double r =
        s0 && i < s0->size() ? s0->radius[static_cast<Eigen::Index>(i)] * map.scale : 0.0;
    particles.push_back(
        {{"t", t}, {"x", x}, {"y", y}, {"r", std::max(round2(r), 2.5)}, {"color", hex_colour(c)}});
  }
  return particles;
}

/// The run's contacts: [t, x, y (pixels), nx, ny, obstacle id].
json contacts_json(const RunData& run, const PixelMap& map) {
  json contacts = json::array();
  for (const auto& c : run.contacts)
    contacts.push_back(
        {c.t, round2(map.px(c.x)), round2(map.py(c.y)), round2(c.nx), round2(c.ny), c.obstacle_id});
  return contacts;
}

/// The page: the template with `data` in its script and `title` in its title.
std::string replay_html(const json& data, const std::string& title) {
  std::string html = kReplayTemplate;
  const std::string marker = "/*PINSIM_DATA*/null";
  const auto at = html.find(marker);
  if (at == std::string::npos) throw std::runtime_error("replay template has no data marker");
  // "</" inside a <script> would end it: JSON allows escaping the slash.
  std::string js = data.dump();
  for (std::size_t k = 0; (k = js.find("</", k)) != std::string::npos; k += 3)
    js.replace(k, 2, "<\\/");
  html.replace(at, marker.size(), js);
  const auto tat = html.find("PINSIM_TITLE");
  if (tat != std::string::npos) html.replace(tat, 12, title);
  return html;
}

}  // namespace

PixelMap write_replay(const RunData& run, const Scene* scene, PluginLoader& loader,
                      const ReplayOptions& opt, const fs::path& out) {
  // Plan: the obstacles' backends, the world rectangle shown and its pixels.
  const ObstacleBackends obstacles = obstacle_backends(scene, loader);
  const ViewBox view = replay_view(run, scene, obstacles, opt);
  const PixelMap map(view, opt.width);
  const double t_end = run.t_end();
  std::optional<State> s0;
  if (scene) s0 = scene->initial_state();
  const State* start = s0 ? &*s0 : nullptr;

  // The pictures and the run: background, moving obstacles, particles, contacts.
  const std::string png = background_png(obstacles, map, view);
  const json moving = moving_json(obstacles, start, map, t_end, opt.obstacle_fps);
  const json particles = particles_json(run, map, start, opt.max_samples);
  const json contacts = contacts_json(run, map);

  // Report: the page with its data, written whole or not at all.
  std::string title = run.label;
  if (scene && !scene->name.empty()) title = scene->name + " — " + run.label;
  const json data = {
      {"title", title},         {"map", map.to_json()},
      {"t_end", t_end},         {"background", "data:image/png;base64," + base64(png)},
      {"particles", particles}, {"contacts", contacts},
      {"moving", moving},       {"summary", run.summary}};
  const std::string html = replay_html(data, title);
  fs::create_directories(fs::absolute(out).parent_path());
  write_file_atomically(out, html);
  return map;
}

}  // namespace pinsim
