// Inputs of the pictures: a run folder's CSV files, the view box of a scene, and the
// world-to-pixel mapping shared by render, replay and play.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/plugin_instance.hpp"
#include "core/scene.hpp"

namespace pinsim {

/// One trajectory.csv row.
struct TrajSample {
  double t, x, y, vx, vy;
};

/// One events.csv row.
struct ContactMark {
  double t;
  int64_t particle, obstacle, other;  ///< obstacle: index if known, else -1
  double x, y, nx, ny, vn_before, vn_after;
  std::string obstacle_id;  ///< as written in events.csv (the obstacle's id), "" for pairs
};

/// A run folder read back: summary.json, trajectory.csv, events.csv.
struct RunData {
  std::filesystem::path dir;
  std::string label;                               ///< short name for legends (folder name)
  nlohmann::json summary;                          ///< summary.json (object, maybe empty)
  std::vector<std::vector<TrajSample>> particles;  ///< per particle, in time order
  std::vector<ContactMark> contacts;

  /// Last recorded time, or 0.
  double t_end() const;
  /// Position of particle i at time t (linear between samples, clamped at the ends).
  Eigen::Vector2d position(std::size_t i, double t) const;
};

/// Reads a run folder. Throws std::runtime_error naming the file and line on bad data.
RunData load_run(const std::filesystem::path& dir);

/// True if `dir` holds a trajectory.csv.
bool is_run_dir(const std::filesystem::path& dir);

/// The run folders below `dir` (one level: e.g. a crosscheck report's per-backend runs).
std::vector<std::filesystem::path> sub_run_dirs(const std::filesystem::path& dir);

/// The scene file a run was made from: summary.json's "scene", tried as given (relative
/// to the working directory), then relative to the run folder and its parents. Empty if
/// not found.
std::filesystem::path run_scene_file(const RunData& run);

/// The scene a run was made from: the folder's scene.json (the document as run, after
/// overrides; relative paths resolved against summary.json's "scene_dir"), else the file
/// run_scene_file finds. Further overrides apply on top. Empty if neither exists.
std::optional<Scene> run_scene(const RunData& run, const std::vector<std::string>& overrides);

/// Axis-aligned world rectangle.
struct ViewBox {
  double x0 = -1, y0 = -1, x1 = 1, y1 = 1;
  void add(double x, double y);
  bool empty() const { return !(x1 > x0 && y1 > y0); }
  /// Grows each side by `frac` of the larger extent.
  void pad(double frac);
};

/// Bounds of the scene's particles and of `obstacles`, padded a little (a unit box if
/// both are empty).
ViewBox scene_view(const Scene& scene, const ViewBox& obstacles);
/// Bounds of the scene's particles and of the backend's obstacles over every pose their
/// motion can take, padded a little.
ViewBox scene_view(const Scene& scene, const BackendInstance& backend);

/// Bounds of the obstacles over every pose their motion can take, as the backend reports
/// them (outline(), PINSIM_CAP_OUTLINES) for `state`; an empty, inverted box if there are
/// none. A backend without outlines gets the empty box and a warning that the view covers
/// the particles only.
ViewBox obstacles_view(const BackendInstance& backend, const State& state);

/// An empty box that any add() replaces.
ViewBox inverted_view();

/// The smallest box holding a and b (empty boxes add nothing).
ViewBox united(ViewBox a, const ViewBox& b);

/// Bounds of a run's trajectories (particle radius `r` added).
void add_run_to_view(const RunData& run, ViewBox& view, double r);

/// World to pixel: y up in the world, down on the image; no margins.
struct PixelMap {
  ViewBox view;
  int width = 0, height = 0;
  double scale = 1;  ///< pixels per world unit
  PixelMap() = default;
  /// `width` pixels across the view; the height follows the view's aspect ratio.
  PixelMap(const ViewBox& v, int width);
  double px(double x) const { return (x - view.x0) * scale; }
  double py(double y) const { return (view.y1 - y) * scale; }
  double wx(double px) const { return view.x0 + px / scale; }
  double wy(double py) const { return view.y1 - py / scale; }
  nlohmann::json to_json() const;
};

/// Parses "x0,y0,x1,y1"; throws std::invalid_argument.
ViewBox parse_view(const std::string& text);

/// Limits of a --view, against `fit` (the rectangle drawn by default) at `width` pixels:
/// finite, overlapping `fit`, its larger side within [1e-3, 1e3] times fit's larger side
/// (cairo would otherwise get radii of ~1e100 pixels and spin in cairo_arc), and a height
/// of at most kMaxPictureHeight pixels. Throws std::invalid_argument naming the limit.
void check_view(const ViewBox& view, const ViewBox& fit, int width);
inline constexpr int kMaxPictureHeight = 8192;

}  // namespace pinsim
