#include "pictures/render.hpp"

#include <cairo-svg.h>
#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>

#include "core/input_error.hpp"
#include "core/output_file.hpp"
#include "core/simulation.hpp"
#include "pictures/cairo_handles.hpp"
#include "pictures/render_field.hpp"

namespace pinsim {
namespace fs = std::filesystem;

void particle_colour(std::size_t run, std::size_t particle, double rgb[3]) {
  // Runs get hue families; particles of one run vary in lightness and hue a little.
  static const double base[6][3] = {{0.85, 0.12, 0.12}, {0.10, 0.35, 0.85}, {0.10, 0.60, 0.25},
                                    {0.60, 0.20, 0.70}, {0.90, 0.55, 0.05}, {0.10, 0.60, 0.65}};
  const double* b = base[run % 6];
  const double k = 1.0 - 0.35 * static_cast<double>(particle % 4) / 3.0;
  const double shift = 0.15 * static_cast<double>((particle / 4) % 3) / 2.0;
  rgb[0] = std::clamp(b[0] * k + shift, 0.0, 1.0);
  rgb[1] = std::clamp(b[1] * k + shift * 0.5, 0.0, 1.0);
  rgb[2] = std::clamp(b[2] * k, 0.0, 1.0);
}

namespace {

void label(cairo_t* cr, double x, double y, const std::string& text, double size) {
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size);
  cairo_text_extents_t e;
  cairo_text_extents(cr, text.c_str(), &e);
  cairo_set_source_rgba(cr, 1, 1, 1, 0.8);
  cairo_rectangle(cr, x - 3, y - size, e.x_advance + 6, size * 1.35);
  cairo_fill(cr);
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
  cairo_move_to(cr, x, y);
  cairo_show_text(cr, text.c_str());
}

std::string fmt_time(double t) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "t = %.3f s", t);
  return buf;
}

using Surface = CairoSurface;

/// Where and how large particles are drawn: radii from the scene, positions from the first
/// run at time t, else the scene's initial state.
struct ParticleLayout {
  const RenderJob& job;
  const PixelMap& map;
  double t = 0.0;
  std::optional<State> s0;  ///< the scene's initial state, if there is a scene
  std::size_t count = 0;    ///< the scene's particles, else the first run's

  ParticleLayout(const RenderJob& j, const PixelMap& m, double time) : job(j), map(m), t(time) {
    if (job.scene) s0 = job.scene->initial_state();
    count = s0 ? s0->size() : (job.runs.empty() ? 0 : job.runs[0].particles.size());
  }
  /// Radius of particle i, pixels (at least 2.5 so that points stay visible).
  double radius_px(std::size_t i) const {
    const double r = s0 && i < s0->size() ? s0->radius[static_cast<Eigen::Index>(i)] : 0.0;
    return std::max(r * map.scale, 2.5);
  }
  /// Position of particle i at time t, world.
  Eigen::Vector2d position(std::size_t i) const {
    if (!job.runs.empty() && i < job.runs[0].particles.size()) return job.runs[0].position(i, t);
    return s0->x.col(static_cast<Eigen::Index>(i));
  }
};

// The world rectangle: the option's, else the scene's bounds grown by the runs' paths
// (runs alone are padded a little).
ViewBox picture_view(const RenderJob& job, const RenderOptions& opt, const Simulation* sim) {
  ViewBox view = job.scene && sim ? scene_view(*job.scene, sim->backend()) : inverted_view();
  for (const auto& run : job.runs) add_run_to_view(run, view, 0.0);
  if (view.empty()) view = ViewBox{};
  if (!job.scene) view.pad(0.05);
  if (!opt.view) return view;
  check_view(*opt.view, view, opt.width);
  return *opt.view;
}

// The time shown: the option's, else the end of the longest run (0 without runs).
double picture_time(const RenderJob& job, const RenderOptions& opt) {
  double t = 0.0;
  for (const auto& run : job.runs) t = std::max(t, run.t_end());
  if (opt.time) t = *opt.time;
  return t;
}

// Collects what cairo writes (cairo_write_func_t).
cairo_status_t append_bytes(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

// An SVG surface writing into `bytes`, or an image surface for a PNG made at the end.
Surface create_surface(const fs::path& out, bool svg, const PixelMap& map, std::string& bytes) {
  fs::create_directories(fs::absolute(out).parent_path());
  Surface surface(
      svg ? cairo_svg_surface_create_for_stream(append_bytes, &bytes, map.width, map.height)
          : cairo_image_surface_create(CAIRO_FORMAT_ARGB32, map.width, map.height));
  if (cairo_surface_status(surface.get()) != CAIRO_STATUS_SUCCESS)
    throw std::runtime_error(out.string() + ": cannot create the picture: " +
                             cairo_status_to_string(cairo_surface_status(surface.get())));
  return surface;
}

// Obstacles: the backend's distance field at time t (sampled twice as finely for SVG),
// shaded with contour lines, or (without the field) only the obstacles filled and outlined.
void draw_obstacles(cairo_t* cr, const Simulation& sim, const PixelMap& map, double t, bool svg,
                    bool field) {
  const BackendInstance& be = sim.backend();
  const FieldGrid g = sample_field(
      [&](double x, double y) { return be.distance(x, y, t, nullptr); }, map, svg ? 2 : 1);
  if (field)
    draw_field(cr, map, g, contour_spacing(map.view));
  else
    draw_solid(cr, g, 0.22, 0.25, 0.30);
}

// Springs and strands: the scene's pair and triple elements, between current positions.
void draw_springs(cairo_t* cr, const Simulation& sim, const ParticleLayout& pl) {
  const PixelMap& map = pl.map;
  cairo_save(cr);
  cairo_set_source_rgba(cr, 0.25, 0.25, 0.30, 0.75);
  cairo_set_line_width(cr, 1.0);
  for (const auto& f : sim.forces()) {
    const uint32_t arity = f->plugin().table->arity;
    if ((arity != 2 && arity != 3) || f->plugin().name() == "gravity") continue;
    const auto& el = f->elements();
    for (std::size_t e = 0; e + arity <= el.size(); e += arity)
      for (uint32_t k = 0; k + 1 < arity; ++k) {
        if (el[e + k] >= pl.count || el[e + k + 1] >= pl.count) continue;
        const auto a = pl.position(el[e + k]), b = pl.position(el[e + k + 1]);
        cairo_move_to(cr, map.px(a.x()), map.py(a.y()));
        cairo_line_to(cr, map.px(b.x()), map.py(b.y()));
      }
  }
  cairo_stroke(cr);
  cairo_restore(cr);
}

// Trajectories up to time t, one colour family per run; later runs dashed so overlaps
// stay visible.
void draw_trajectories(cairo_t* cr, const RenderJob& job, const PixelMap& map, double t) {
  for (std::size_t k = 0; k < job.runs.size(); ++k) {
    const auto& run = job.runs[k];
    cairo_save(cr);
    cairo_set_line_width(cr, job.runs.size() > 1 ? 1.6 : 1.2);
    cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
    if (k > 0) {
      const double dash[2] = {6.0, 4.0};
      cairo_set_dash(cr, dash, 2, 0);
    }
    for (std::size_t i = 0; i < run.particles.size(); ++i) {
      const auto& p = run.particles[i];
      if (p.size() < 2) continue;
      double c[3];
      particle_colour(k, i, c);
      cairo_set_source_rgba(cr, c[0], c[1], c[2], 0.85);
      cairo_move_to(cr, map.px(p[0].x), map.py(p[0].y));
      for (std::size_t s = 1; s < p.size() && p[s].t <= t + 1e-12; ++s)
        cairo_line_to(cr, map.px(p[s].x), map.py(p[s].y));
      cairo_stroke(cr);
    }
    cairo_restore(cr);
  }
}

// Contacts up to time t: a ring at the contact point and a tick along the normal.
void draw_contacts(cairo_t* cr, const RenderJob& job, const PixelMap& map, double t) {
  for (std::size_t k = 0; k < job.runs.size(); ++k) {
    cairo_save(cr);
    cairo_set_line_width(cr, 1.3);
    if (k == 0)
      cairo_set_source_rgba(cr, 0.95, 0.50, 0.0, 0.9);
    else
      cairo_set_source_rgba(cr, 0.0, 0.55, 0.85, 0.9);
    for (const auto& c : job.runs[k].contacts) {
      if (c.t > t + 1e-12) continue;
      const double x = map.px(c.x), y = map.py(c.y);
      cairo_new_sub_path(cr);
      cairo_arc(cr, x, y, 3.5, 0, 2 * M_PI);
      cairo_move_to(cr, x, y);
      cairo_line_to(cr, x + 10 * c.nx, y - 10 * c.ny);
    }
    cairo_stroke(cr);
    cairo_restore(cr);
  }
}

// A filled disc with a dark outline.
void disc(cairo_t* cr, double x, double y, double r, const double c[3]) {
  cairo_new_sub_path(cr);
  cairo_arc(cr, x, y, r, 0, 2 * M_PI);
  cairo_set_source_rgb(cr, c[0], c[1], c[2]);
  cairo_fill_preserve(cr);
  cairo_set_source_rgb(cr, 0.08, 0.08, 0.08);
  cairo_set_line_width(cr, 0.8);
  cairo_stroke(cr);
}

// Particles at time t: every run's, the first run on top (so a crosscheck shows where each
// backend ended), or the scene's initial ones without runs.
void draw_particles(cairo_t* cr, const ParticleLayout& pl) {
  const RenderJob& job = pl.job;
  const PixelMap& map = pl.map;
  if (job.runs.empty()) {
    for (std::size_t i = 0; i < pl.count; ++i) {
      double c[3];
      particle_colour(0, i, c);
      const auto p = pl.position(i);
      disc(cr, map.px(p.x()), map.py(p.y()), pl.radius_px(i), c);
    }
    return;
  }
  for (std::size_t k = job.runs.size(); k-- > 0;)
    for (std::size_t i = 0; i < job.runs[k].particles.size(); ++i) {
      double c[3];
      particle_colour(k, i, c);
      const auto p = job.runs[k].position(i, pl.t);
      disc(cr, map.px(p.x()), map.py(p.y()), pl.radius_px(i), c);
    }
}

// The title (the option's, else the scene's name and the time) and, for several runs, a
// legend of their colours.
void draw_title_and_legend(cairo_t* cr, const RenderJob& job, const RenderOptions& opt,
                           const PixelMap& map, double t) {
  std::string title = opt.title;
  if (title.empty()) {
    if (job.scene) title = job.scene->name.empty() ? job.scene->label : job.scene->name;
    if (!job.runs.empty() || opt.time) title += (title.empty() ? "" : ", ") + fmt_time(t);
  }
  const double fs_px = std::clamp(map.width / 55.0, 10.0, 16.0);
  if (!title.empty()) label(cr, 8, 6 + fs_px, title, fs_px);
  if (job.runs.size() <= 1) return;
  for (std::size_t k = 0; k < job.runs.size(); ++k) {
    const double y = 6 + fs_px * (2.6 + 1.5 * static_cast<double>(k));
    double c[3];
    particle_colour(k, 0, c);
    std::string name = job.runs[k].label;
    if (job.runs[k].summary.contains("backend"))
      name += " (" + job.runs[k].summary["backend"].get<std::string>() + ")";
    label(cr, 8 + 2.2 * fs_px, y, name, fs_px);
    cairo_set_source_rgb(cr, c[0], c[1], c[2]);
    cairo_rectangle(cr, 8, y - 0.75 * fs_px, 1.6 * fs_px, 0.75 * fs_px);
    cairo_fill(cr);
  }
}

// Encodes the PNG, or finishes the SVG the surface has been writing into `bytes`; then
// writes `out` atomically (OutputError naming it), so no half picture is ever left.
void write_picture(cairo_surface_t* surface, const fs::path& out, bool svg, std::string& bytes) {
  if (!svg) {
    const cairo_status_t st = cairo_surface_write_to_png_stream(surface, append_bytes, &bytes);
    if (st != CAIRO_STATUS_SUCCESS)
      throw std::runtime_error(out.string() + ": cannot encode: " + cairo_status_to_string(st));
  } else {
    cairo_surface_finish(surface);
    if (cairo_surface_status(surface) != CAIRO_STATUS_SUCCESS)
      throw std::runtime_error(out.string() + ": cannot encode: " +
                               cairo_status_to_string(cairo_surface_status(surface)));
  }
  write_file_atomically(out, bytes);
}

}  // namespace

PixelMap render_picture(const RenderJob& job, PluginLoader& loader, const RenderOptions& opt,
                        const fs::path& out) {
  const std::string ext = out.extension().string();
  if (ext != ".png" && ext != ".svg")
    throw InputError(out.string() + ": the picture must be a .png or .svg file");
  const bool svg = ext == ".svg";
  // The scene's plugins and backend (for the distance field and the springs).
  std::unique_ptr<Simulation> sim;
  if (job.scene) sim = std::make_unique<Simulation>(*job.scene, loader);
  // What is shown, where and when.
  const PixelMap map(picture_view(job, opt, sim.get()), opt.width);
  const double t = picture_time(job, opt);
  const ParticleLayout particles(job, map, t);
  // The layers from the bottom up, on a light background.
  std::string bytes;  // the file's bytes: the SVG surface writes here as it draws
  Surface surface = create_surface(out, svg, map, bytes);
  CairoContext ctx = cairo_context(surface.get());
  cairo_t* cr = ctx.get();
  cairo_set_source_rgb(cr, 0.97, 0.95, 0.90);
  cairo_paint(cr);
  if (sim && sim->backend().has_distance()) draw_obstacles(cr, *sim, map, t, svg, opt.field);
  if (sim) draw_springs(cr, *sim, particles);
  if (opt.trajectories) draw_trajectories(cr, job, map, t);
  if (opt.contacts) draw_contacts(cr, job, map, t);
  draw_particles(cr, particles);
  draw_title_and_legend(cr, job, opt, map, t);
  ctx.reset();
  write_picture(surface.get(), out, svg, bytes);
  return map;
}

}  // namespace pinsim
