#include "pictures/render_data.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/format.hpp"
#include "core/json_read.hpp"
#include "core/trajectory_hdf5.hpp"

namespace pinsim {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// Splits one CSV line of numbers; false if a field is not a number.
bool parse_numbers(const std::string& line, std::vector<double>& out) {
  out.clear();
  const char* p = line.c_str();
  while (*p) {
    char* end = nullptr;
    const double v = std::strtod(p, &end);
    if (end == p) return false;
    out.push_back(v);
    p = end;
    if (*p == ',')
      ++p;
    else if (*p == '\r' || *p == '\0')
      break;
    else
      return false;
  }
  return true;
}

/// Reads a CSV file with the expected header; calls `row` with each line's numbers.
template <class F>
void read_csv(const fs::path& file, const std::string& header, std::size_t fields, F row) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot open");
  std::string line;
  if (!std::getline(in, line) || line.rfind(header, 0) != 0)
    throw std::runtime_error(file.string() + ":1: expected the header '" + header + "'");
  std::vector<double> v;
  for (std::size_t n = 2; std::getline(in, line); ++n) {
    if (line.empty()) continue;
    if (!parse_numbers(line, v) || v.size() != fields)
      throw std::runtime_error(file.string() + ":" + std::to_string(n) + ": expected " +
                               std::to_string(fields) + " numbers");
    try {
      row(v);
    } catch (const std::invalid_argument& e) {  // a row's value out of place: name the line
      throw std::runtime_error(file.string() + ":" + std::to_string(n) + ": " + e.what());
    }
  }
}

/// A particle index read as a double: an integer in [0, count), else invalid_argument
/// saying `expected`. (Checked before the cast: a double past the integer range would be
/// undefined behaviour.)
std::size_t particle_index(double v, std::size_t count, const std::string& expected) {
  if (!(v >= 0 && v < static_cast<double>(count) && v == std::floor(v)))
    throw std::invalid_argument(fmt::format("particle index {}: expected ", v) + expected);
  return static_cast<std::size_t>(v);
}

using Vec = Eigen::Vector2d;

}  // namespace

ViewBox inverted_view() {
  ViewBox v;
  v.x0 = v.y0 = HUGE_VAL;
  v.x1 = v.y1 = -HUGE_VAL;
  return v;
}
double RunData::t_end() const {
  double t = 0;
  for (const auto& p : particles)
    if (!p.empty()) t = std::max(t, p.back().t);
  return t;
}

Eigen::Vector2d RunData::position(std::size_t i, double t) const {
  const auto& s = particles.at(i);
  if (s.empty()) return Vec::Zero();
  if (t <= s.front().t) return Vec(s.front().x, s.front().y);
  if (t >= s.back().t) return Vec(s.back().x, s.back().y);
  const auto it = std::upper_bound(s.begin(), s.end(), t,
                                   [](double v, const TrajSample& a) { return v < a.t; });
  const TrajSample& b = *it;
  const TrajSample& a = *(it - 1);
  const double w = b.t > a.t ? (t - a.t) / (b.t - a.t) : 1.0;
  return Vec(a.x + w * (b.x - a.x), a.y + w * (b.y - a.y));
}

bool is_run_dir(const fs::path& dir) {
  return fs::is_regular_file(dir / "trajectory.csv") || fs::is_regular_file(dir / "trajectory.h5");
}

std::vector<fs::path> sub_run_dirs(const fs::path& dir) {
  std::vector<fs::path> out;
  if (!fs::is_directory(dir)) return out;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_directory() && is_run_dir(e.path())) out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

RunData load_run(const fs::path& dir) {
  RunData r;
  r.dir = dir;
  r.label = fs::absolute(dir).lexically_normal().filename().string();
  if (r.label.empty()) r.label = fs::absolute(dir).lexically_normal().parent_path().filename();
  if (fs::exists(dir / "summary.json")) {
    r.summary = read_json_file(dir / "summary.json");  // errors name the file
  }
  if (!fs::exists(dir / "trajectory.csv") && fs::exists(dir / "trajectory.h5")) {
    // output.format "hdf5": the frames the file says are complete, the same samples the
    // CSV would hold (exact doubles).
    const Hdf5Trajectory h = read_hdf5_trajectory(dir / "trajectory.h5");
    r.particles.assign(h.particles, {});
    for (std::size_t i = 0; i < h.particles; ++i) {
      r.particles[i].reserve(h.frames());
      for (std::size_t f = 0; f < h.frames(); ++f) {
        const std::size_t k = f * h.particles + i;
        r.particles[i].push_back({h.t[f], h.x[k], h.y[k], h.vx[k], h.vy[k]});
      }
    }
  } else {
    // pinsim writes every particle in every frame, in order: a particle index is one seen
    // before or the next one, so the series grow with the file (an index of 10^7 in a small
    // file once made render run for minutes and replay take gigabytes).
    read_csv(dir / "trajectory.csv", "t,particle,x,y,vx,vy", 6, [&](const std::vector<double>& v) {
      const std::size_t i =
          particle_index(v[1], r.particles.size() + 1,
                         "an integer from 0 to " + std::to_string(r.particles.size()) +
                             " (each frame lists the particles 0, 1, 2, ... in order)");
      if (r.particles.size() == i) r.particles.emplace_back();
      r.particles[i].push_back({v[0], v[2], v[3], v[4], v[5]});
    });
  }
  if (fs::exists(dir / "events.csv") && !fs::is_regular_file(dir / "events.csv"))
    throw std::runtime_error((dir / "events.csv").string() +
                             ": not a regular file (a folder, pipe or device)");
  if (fs::exists(dir / "events.csv")) {
    // The obstacle column holds the obstacle's id (or index); other_particle may be empty.
    const fs::path file = dir / "events.csv";
    std::ifstream in(file);
    std::string line;
    std::getline(in, line);
    if (line.rfind("t,particle,obstacle,other_particle,x,y,nx,ny,vn_before,vn_after", 0) != 0)
      throw std::runtime_error(file.string() + ":1: unexpected header");
    std::vector<std::string> f;
    for (std::size_t n = 2; std::getline(in, line); ++n) {
      if (line.empty()) continue;
      f.clear();
      std::stringstream ss(line);
      for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
      if (f.size() == 9 && line.back() == ',') f.emplace_back();
      auto num = [&](std::size_t k) {
        char* end = nullptr;
        const double v = std::strtod(f[k].c_str(), &end);
        if (f[k].empty() || *end != '\0')
          throw std::runtime_error(file.string() + ":" + std::to_string(n) + ": field " +
                                   std::to_string(k + 1) + " is not a number");
        return v;
      };
      if (f.size() != 10)
        throw std::runtime_error(file.string() + ":" + std::to_string(n) + ": expected 10 fields");
      auto index = [&](std::size_t k) {
        try {
          return static_cast<int64_t>(particle_index(
              num(k), r.particles.size(),
              "one of the trajectory's " + std::to_string(r.particles.size()) +
                  " particles, an integer below " + std::to_string(r.particles.size())));
        } catch (const std::invalid_argument& e) {
          throw std::runtime_error(file.string() + ":" + std::to_string(n) + ": field " +
                                   std::to_string(k + 1) + ": " + e.what());
        }
      };
      ContactMark c{};
      c.t = num(0);
      c.particle = index(1);
      c.obstacle_id = f[2];
      c.obstacle = -1;
      c.other = f[3].empty() ? -1 : index(3);
      c.x = num(4), c.y = num(5), c.nx = num(6), c.ny = num(7);
      c.vn_before = num(8), c.vn_after = num(9);
      r.contacts.push_back(c);
    }
  }
  return r;
}

std::optional<Scene> run_scene(const RunData& run, const std::vector<std::string>& overrides) {
  const fs::path stored = run.dir / "scene.json";
  if (fs::is_regular_file(stored)) {
    std::ifstream in(stored);
    std::stringstream text;
    text << in.rdbuf();
    fs::path base = run.dir;
    if (run.summary.is_object() && run.summary.contains("scene_dir") &&
        run.summary["scene_dir"].is_string())
      base = run.summary["scene_dir"].get<std::string>();
    return parse_scene(text.str(), stored.string(), base, overrides);
  }
  const fs::path file = run_scene_file(run);
  if (file.empty()) return std::nullopt;
  return load_scene(file, overrides);
}

fs::path run_scene_file(const RunData& run) {
  if (!run.summary.is_object() || !run.summary.contains("scene") ||
      !run.summary["scene"].is_string())
    return {};
  const fs::path s = run.summary["scene"].get<std::string>();
  if (s.empty() || s.string().front() == '<') return {};  // the embedded scene
  if (fs::is_regular_file(s)) return s;
  for (fs::path d = fs::absolute(run.dir); !d.empty(); d = d.parent_path()) {
    if (fs::is_regular_file(d / s)) return d / s;
    if (d == d.parent_path()) break;
  }
  return {};
}

void ViewBox::add(double x, double y) {
  if (!std::isfinite(x) || !std::isfinite(y)) return;
  x0 = std::min(x0, x);
  x1 = std::max(x1, x);
  y0 = std::min(y0, y);
  y1 = std::max(y1, y);
}

void ViewBox::pad(double frac) {
  const double e = frac * std::max(x1 - x0, y1 - y0);
  x0 -= e;
  x1 += e;
  y0 -= e;
  y1 += e;
}

ViewBox united(ViewBox a, const ViewBox& b) {
  if (!b.empty()) {
    a.add(b.x0, b.y0);
    a.add(b.x1, b.y1);
  }
  return a;
}

ViewBox obstacles_view(const BackendInstance& backend, const State& state) {
  ViewBox v = inverted_view();
  if (!backend.has_outline()) {
    spdlog::warn(
        "backend '{}' does not report its obstacles' outlines (no PINSIM_CAP_OUTLINES): the "
        "picture's view covers the particles only (render and replay set another with --view; "
        "play and share have no other; FieldBackend in pinsim/scene_field.hpp gives a backend "
        "outline())",
        backend.plugin().name());
    return v;
  }
  const pinsim_bounds b = backend.outline(state, 0.0).sweep;
  if (b.x0 <= b.x1 && b.y0 <= b.y1) {
    v.add(b.x0, b.y0);
    v.add(b.x1, b.y1);
  }
  return v;
}

ViewBox scene_view(const Scene& scene, const BackendInstance& backend) {
  return scene_view(scene, obstacles_view(backend, scene.initial_state()));
}

ViewBox scene_view(const Scene& scene, const ViewBox& obstacles) {
  ViewBox v = obstacles;
  const State s = scene.initial_state();
  for (Eigen::Index k = 0; k < s.x.cols(); ++k) {
    const double r = s.radius[k];
    v.add(s.x(0, k) - r, s.x(1, k) - r);
    v.add(s.x(0, k) + r, s.x(1, k) + r);
  }
  if (v.empty()) v = ViewBox{};
  if (v.x1 - v.x0 < 1e-9 || v.y1 - v.y0 < 1e-9) {
    const double cx = 0.5 * (v.x0 + v.x1), cy = 0.5 * (v.y0 + v.y1);
    v = ViewBox{cx - 1, cy - 1, cx + 1, cy + 1};
  }
  v.pad(0.03);
  return v;
}

void add_run_to_view(const RunData& run, ViewBox& view, double r) {
  for (const auto& p : run.particles)
    for (const auto& s : p) {
      view.add(s.x - r, s.y - r);
      view.add(s.x + r, s.y + r);
    }
}

PixelMap::PixelMap(const ViewBox& v, int w) : view(v), width(std::max(w, 16)) {
  scale = width / (v.x1 - v.x0);
  height = std::max(16, static_cast<int>(std::lround((v.y1 - v.y0) * scale)));
}

json PixelMap::to_json() const {
  return {{"x0", view.x0},  {"y0", view.y0},    {"x1", view.x1}, {"y1", view.y1},
          {"width", width}, {"height", height}, {"scale", scale}};
}

ViewBox parse_view(const std::string& text) {
  std::vector<double> v;
  if (!parse_numbers(text, v) || v.size() != 4 || !(v[2] > v[0]) || !(v[3] > v[1]))
    throw std::invalid_argument("--view: expected x0,y0,x1,y1 with x1 > x0 and y1 > y0, got '" +
                                text + "'");
  return ViewBox{v[0], v[1], v[2], v[3]};
}

void check_view(const ViewBox& v, const ViewBox& fit, int width) {
  // (appended piece by piece: GCC 12 warns wrongly of overlap in "literal" + string)
  std::string given = "--view ";
  given.append(num(v.x0)).append(",").append(num(v.y0)).append(",").append(num(v.x1));
  given.append(",").append(num(v.y1)).append(": ");
  const double w = v.x1 - v.x0, h = v.y1 - v.y0;
  if (!(std::isfinite(w) && std::isfinite(h) && w > 0.0 && h > 0.0))
    throw std::invalid_argument(given + "expected finite corners with x1 > x0 and y1 > y0");
  const double size = std::max(fit.x1 - fit.x0, fit.y1 - fit.y0);
  std::string fit_text = "[";
  fit_text.append(num(fit.x0)).append(", ").append(num(fit.x1)).append("] x [");
  fit_text.append(num(fit.y0)).append(", ").append(num(fit.y1)).append("]");
  if (!(std::max(w, h) >= 1e-3 * size && std::max(w, h) <= 1e3 * size))
    throw std::invalid_argument(given + "its larger side " + num(std::max(w, h)) +
                                " must be between 1e-3 and 1e3 times the picture's default " +
                                "size " + num(size) + " (the scene and runs, " + fit_text + ")");
  if (v.x1 < fit.x0 || v.x0 > fit.x1 || v.y1 < fit.y0 || v.y0 > fit.y1)
    throw std::invalid_argument(given + "does not overlap the scene and runs, " + fit_text);
  const double height = h / w * width;
  if (!(height <= kMaxPictureHeight))
    throw std::invalid_argument(given + "gives a picture " + num(height) + " pixels high at " +
                                std::to_string(width) + " wide, more than the limit of " +
                                std::to_string(kMaxPictureHeight));
}

}  // namespace pinsim
