#include "tools/stress.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include "core/format.hpp"
#include "core/json_read.hpp"
#include "core/simulation.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace pinsim::stress {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Case {
  std::string name, kind;  ///< kind: stiffness | tunnelling | run
  json doc;
  fs::path base;
  std::string stiffness_path;  ///< stiffness: the override path of the stiffness
  double blowup = 1.0;         ///< energy growth that counts as a blow-up (x energy scale)
  double pen_tol = 0.0;        ///< penetration deeper than this is a failure, length
  /// A free particle farther than this from where it started has diverged (length; 0: off).
  /// For bounded potentials (bending: |E| <= k/2) an unstable step makes the strand tumble
  /// rather than blow its energy up, so the energy test alone cannot see the instability.
  double displacement_limit = 0.0;
};

struct Point {
  std::size_t index, case_index;
  json backend;
  std::string integrator;
  double dt, stiffness = kNaN, speed = kNaN, thickness = kNaN;
};

// A ball of radius 0.05 at x = -1 flying at `speed` along +x at a wall (a box of the given
// thickness centred on x = 0, 2 tall), for the time it needs to travel 2 units.
json tunnelling_scene(double speed, double thickness, double dt) {
  const double T = dt * std::ceil(2.0 / speed / dt);
  return {{"time", {{"dt", dt}, {"duration", T}}},
          {"particles", {{{"x", {-1.0, 0.0}}, {"v", {speed, 0.0}}, {"radius", 0.05}}}},
          {"obstacles",
           {{{"id", "wall"},
             {"shape",
              {{"type", "box"}, {"center", {0.0, 0.0}}, {"half_size", {0.5 * thickness, 1.0}}}},
             {"material", {{"restitution", 1.0}}}}}}};
}

double omega_max(const Scene& scene, PluginLoader& loader) {
  Simulation sim(scene, loader);
  Eigen::SparseMatrix<double> K, D;
  sim.assemble_jacobians(sim.state(), K, D);
  const State& s = sim.state();
  std::vector<Eigen::Index> free;
  for (Eigen::Index i = 0; i < 2 * static_cast<Eigen::Index>(s.size()); ++i)
    if (s.inv_mass[i / 2] > 0.0) free.push_back(i);
  const auto n = static_cast<Eigen::Index>(free.size());
  if (n == 0 || n > 2000) return kNaN;
  const Eigen::MatrixXd Kd(K);
  Eigen::MatrixXd A(n, n);
  for (Eigen::Index a = 0; a < n; ++a)
    for (Eigen::Index b = 0; b < n; ++b)
      A(a, b) =
          -Kd(free[a], free[b]) * std::sqrt(s.inv_mass[free[a] / 2] * s.inv_mass[free[b] / 2]);
  A = 0.5 * (A + A.transpose()).eval();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(A, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, es.eigenvalues().maxCoeff()));
}

struct Outcome {
  std::string cls = "stable";
  long long bad_step = -1, particle = -1;
  double max_pen = 0.0, drift = kNaN, wall = 0.0;
  uint64_t steps = 0;
};

Outcome run_point(const Case& c, const Point& p, PluginLoader& loader) {
  json doc = c.kind == "tunnelling" ? tunnelling_scene(p.speed, p.thickness, p.dt) : c.doc;
  std::vector<std::pair<std::string, json>> set = {{"time.dt", p.dt},
                                                   {"integrator", p.integrator},
                                                   {"checks.energy_every", 1},
                                                   {"checks.energy_blowup", c.blowup},
                                                   {"checks.kinetic_growth", 0}};
  if (!p.backend.is_null()) set.emplace_back("backend", p.backend);
  if (!c.stiffness_path.empty()) set.emplace_back(c.stiffness_path, p.stiffness);
  const Scene scene = sweep::make_scene(doc, set, c.name, c.base);
  Outcome o;
  Simulation sim(scene, loader);
  const bool dist = sim.backend().has_distance();
  const uint64_t N = scene.steps();
  if (N == 0) {  // no step: nothing was tested, so the point is an error, never "stable"
    o.cls =
        "error: dt " + num(p.dt) + " s makes no step in the scene's " + num(scene.duration) + " s";
    return o;
  }
  const Eigen::Matrix2Xd x0 = sim.state().x;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    for (uint64_t n = 1; n <= N && o.cls != "diverged"; ++n) {
      sim.step();
      const State& s = sim.state();
      if (c.displacement_limit > 0.0)
        for (Eigen::Index i = 0; i < s.x.cols() && o.cls != "diverged"; ++i)
          if (s.inv_mass[i] > 0.0 && !((s.x.col(i) - x0.col(i)).norm() <= c.displacement_limit)) {
            o.cls = "diverged";
            o.bad_step = static_cast<long long>(n);
            o.particle = i;
          }
      if (dist) {
        for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
          if (!(s.inv_mass[i] > 0.0)) continue;
          const double pen =
              s.radius[i] - sim.backend().distance(s.x(0, i), s.x(1, i), s.t, nullptr);
          if (pen > o.max_pen) o.max_pen = pen;
          if (pen > c.pen_tol && o.cls == "stable") {
            o.cls = "penetration";
            o.bad_step = static_cast<long long>(n);
            o.particle = i;
          }
        }
      }
      if (c.kind == "tunnelling" && s.x(0, 0) > 0.0 && o.cls != "tunnelled") {
        o.cls = "tunnelled";
        o.bad_step = static_cast<long long>(n);
        o.particle = 0;
      }
    }
  } catch (const NumericError& e) {
    o.cls = e.kind == NumericError::Kind::EnergyBlowup    ? "energy_blowup"
            : e.kind == NumericError::Kind::SolverFailure ? "solver_failure"
                                                          : "nan";
    o.bad_step = static_cast<long long>(e.step);
    o.particle = e.particle;
  }
  o.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  o.steps = sim.step_index();
  o.drift = sim.energy_complete() ? sim.max_energy_drift() : kNaN;
  return o;
}

int class_code(const std::string& c) {
  if (c == "stable") return 0;
  if (c == "penetration") return 1;
  if (c == "tunnelled") return 2;
  if (c == "energy_blowup" || c == "diverged") return 3;
  if (c == "nan" || c == "solver_failure") return 4;
  return 5;
}

/// Checks case `ci` of the config (its keys and limits, each limit from the case or else the
/// config's top level) and reads it, its scene included; its kind's axes come later.
Case read_case(const sweep::Config& cfg, const json& cj, std::size_t ci,
               const sweep::CaseAt& where) {
  const json& d = cfg.doc;
  const std::string& cw = where.where;
  const Loc& at = where.at;
  const Loc top{cfg.file.string(), ""};
  check_keys(cj,
             {"name", "kind", "scene", "dt", "integrators", "backends", "energy_blowup",
              "penetration_tolerance", "displacement_limit", "stiffness", "speeds", "thickness"},
             at);
  Case c;
  c.name = read_string_or(cj, "name", "case" + std::to_string(ci), at);
  c.kind = read_string_or(cj, "kind", "run", at);
  c.blowup = read_number_or(cj, "energy_blowup", read_number_or(d, "energy_blowup", 1.0, top), at);
  c.pen_tol = read_number_or(cj, "penetration_tolerance",
                             read_number_or(d, "penetration_tolerance", 1e-3, top), at);
  c.displacement_limit = read_number_or(cj, "displacement_limit", 0.0, at);
  // Checked here, once (as the schema says): a blow-up factor <= 0 once made every point
  // an "error" row and the sweep exit 0.
  const auto where_of = [&](const char* key) { return cj.contains(key) ? at / key : top / key; };
  if (!(c.blowup > 0.0 && c.blowup < HUGE_VAL))
    where_of("energy_blowup").fail("must be a number > 0, got " + num(c.blowup));
  if (!(c.pen_tol >= 0.0 && c.pen_tol < HUGE_VAL))
    where_of("penetration_tolerance").fail("must be a number >= 0, got " + num(c.pen_tol));
  if (!(c.displacement_limit >= 0.0 && c.displacement_limit < HUGE_VAL))
    (at / "displacement_limit")
        .fail("must be a number >= 0 (0: off), got " + num(c.displacement_limit));
  if (c.kind != "tunnelling") {
    if (!cj.contains("scene")) throw InputError(cw + ".scene: required");
    c.doc = sweep::scene_doc(cfg, cj["scene"], c.base);
  } else {
    c.base = cfg.dir;
  }
  return c;
}

/// The axes only some kinds have: stiffness values (and the path they override), ball
/// speeds and wall thicknesses; one NaN for an axis the kind does not have.
struct KindAxes {
  std::vector<double> ks = {kNaN}, speeds = {kNaN}, thick = {kNaN};
};

/// Reads case `c`'s kind axes from its JSON `cj` (and sets c.stiffness_path); InputError for
/// an unknown kind.
KindAxes read_kind_axes(const json& cj, const sweep::CaseAt& where, Case& c) {
  const std::string& cw = where.where;
  const Loc& at = where.at;
  KindAxes k;
  if (c.kind == "stiffness") {
    if (!cj.contains("stiffness") || !cj["stiffness"].is_object())
      throw InputError(cw + ".stiffness: expected {\"path\": ..., \"values\": [...]}");
    check_keys(cj["stiffness"], {"path", "values"}, at / "stiffness");
    c.stiffness_path = read_string_or(cj["stiffness"], "path", "", at / "stiffness");
    k.ks = sweep::numbers(cj["stiffness"].value("values", json()), cw + ".stiffness.values");
  } else if (c.kind == "tunnelling") {
    k.speeds = sweep::numbers(cj.value("speeds", json()), cw + ".speeds");
    k.thick = sweep::numbers(cj.value("thickness", json()), cw + ".thickness");
  } else if (c.kind != "run") {
    throw InputError(cw + ".kind: expected stiffness, tunnelling or run");
  }
  return k;
}

/// What a stress config asks for: its cases and the points crossing their axes (backends
/// outermost, dt innermost).
struct Plan {
  std::vector<Case> cases;
  std::vector<Point> points;
};

/// Reads and checks the whole config; InputError names what is wrong and where.
Plan read_plan(const sweep::Config& cfg) {
  const json& d = cfg.doc;
  const std::string where = cfg.file.string();
  const json& cases_j = sweep::cases(cfg);
  check_keys(d,
             {"$schema", "description", "cases", "integrators", "backends", "dt", "energy_blowup",
              "penetration_tolerance"},
             {where, ""});
  Plan plan;
  for (std::size_t ci = 0; ci < cases_j.size(); ++ci) {
    const json& cj = cases_j[ci];
    const sweep::CaseAt where = sweep::case_at(cfg, ci);
    Case c = read_case(cfg, cj, ci, where);
    const sweep::Axes ax = sweep::case_axes(cfg, cj, where.where);
    const KindAxes kx = read_kind_axes(cj, where, c);
    for (const json& b : ax.backends)
      for (const std::string& in : ax.integrators)
        for (double k : kx.ks)
          for (double sp : kx.speeds)
            for (double th : kx.thick)
              for (double dt : ax.dts) {
                Point p{plan.points.size(), plan.cases.size(), b, in, dt};
                p.stiffness = k;
                p.speed = sp;
                p.thickness = th;
                plan.points.push_back(p);
              }
    plan.cases.push_back(std::move(c));
  }
  return plan;
}

/// What makes shards parts of one sweep: the config and every case's scene.
std::string inputs_of(const sweep::Config& cfg, const Plan& plan) {
  std::vector<const json*> scenes;
  for (const Case& c : plan.cases) scenes.push_back(&c.doc);
  return sweep::sweep_inputs("stress", cfg, "", scenes);
}

/// Runs the points of a plan, each to its CSV row and a log line; a stiffness case's w_max
/// is computed once per stiffness and kept.
class PointRunner {
 public:
  explicit PointRunner(const Plan& plan) : plan_(plan), loader_(plugin_search_dirs()) {}

  std::vector<std::string> operator()(std::size_t i) {
    const Point& p = plan_.points[i];
    const Case& c = plan_.cases[p.case_index];
    const double w = omega(p, c);
    Outcome r;
    try {
      r = run_point(c, p, loader_);
    } catch (const std::exception& e) {
      r.cls = std::string("error: ") + e.what();
      std::replace(r.cls.begin(), r.cls.end(), ',', ';');
      std::replace(r.cls.begin(), r.cls.end(), '\n', ' ');
    }
    const auto it = p.backend.is_object() ? p.backend.find("name") : p.backend.end();
    const std::string bname = it == p.backend.end() ? (p.backend.is_object() ? "?" : "scene")
                              : it->is_string()     ? it->get<std::string>()
                                                    : "?";
    spdlog::info("[{}/{}] {} {} {} dt={} k={} v={} w={}: {} (step {}, particle {})", p.index + 1,
                 plan_.points.size(), c.name, bname, p.integrator, p.dt, num(p.stiffness),
                 num(p.speed), num(p.thickness), r.cls, r.bad_step, r.particle);
    return {std::to_string(p.index),
            c.name,
            c.kind,
            bname,
            p.integrator,
            num(p.dt),
            num(p.stiffness),
            num(w),
            num(p.dt * w),
            num(p.speed),
            num(p.thickness),
            r.cls,
            std::to_string(r.bad_step),
            std::to_string(r.particle),
            num(r.max_pen),
            num(r.drift),
            std::to_string(r.steps),
            num(r.wall)};
  }

 private:
  /// A stiffness case's w_max at point p's stiffness; NaN for the other kinds.
  double omega(const Point& p, const Case& c) {
    if (c.kind != "stiffness") return kNaN;
    auto key = std::make_pair(p.case_index, p.stiffness);
    if (!wmax_.count(key))
      wmax_[key] = omega_max(
          sweep::make_scene(c.doc, {{c.stiffness_path, p.stiffness}}, c.name, c.base), loader_);
    return wmax_[key];
  }

  const Plan& plan_;
  PluginLoader loader_;
  std::map<std::pair<std::size_t, double>, double> wmax_;
};

}  // namespace

double theory_limit(const std::string& in) {
  if (in == "symplectic_euler" || in == "velocity_verlet") return 2.0;
  if (in == "rk4") return 2.0 * std::sqrt(2.0);
  if (in == "explicit_euler") return 0.0;
  if (in == "implicit_euler" || in == "xpbd") return std::numeric_limits<double>::infinity();
  return kNaN;
}

const std::vector<std::string>& columns() {
  static const std::vector<std::string> c = {
      "point",        "case",      "kind",           "backend",  "integrator",
      "dt",           "stiffness", "omega_max",      "h_omega",  "speed",
      "thickness",    "class",     "first_bad_step", "particle", "max_penetration",
      "energy_drift", "steps",     "wall_s"};
  return c;
}

int run(const Options& o) {
  const sweep::Config cfg = sweep::load_config(o.config);
  const Plan plan = read_plan(cfg);
  if (o.check_only) return 0;
  PointRunner points(plan);
  sweep::Sweep sw;
  sw.tool = "stress";
  sw.columns = columns();
  sw.points = plan.points.size();
  sw.inputs = inputs_of(cfg, plan);
  sw.run_point = std::ref(points);
  sw.report = report;
  return sweep::exit_code(sweep::drive(sw, o.shard, o.out, cfg.file.string(), o.resume), 0);
}

void report(const sweep::Table& t, const fs::path& out) {
  const auto cc = t.col("case"), ck = t.col("kind"), cb = t.col("backend"),
             ci = t.col("integrator"), cd = t.col("dt"), cs = t.col("stiffness"),
             chw = t.col("h_omega"), cl = t.col("class"), csp = t.col("speed"),
             cth = t.col("thickness"), cp = t.col("max_penetration"), ce = t.col("energy_drift");
  // Stability limits: per (case, backend, integrator, stiffness), sorted by dt: the last
  // h w with every smaller dt stable, and the first unstable h w.
  // Stiffness orders as a number (100 before 400 before 1600), not as text.
  using GroupKey = std::tuple<std::string, std::string, std::string, double, std::string>;
  std::map<GroupKey, std::vector<std::pair<double, const std::vector<std::string>*>>> groups;
  for (const auto& r : t.rows)
    if (r[ck] == "stiffness")
      groups[GroupKey{r[cc], r[cb], r[ci], std::strtod(r[cs].c_str(), nullptr), r[cs]}].push_back(
          {std::stod(r[cd]), &r});
  if (!groups.empty()) {
    std::cout << "\nempirical stability limit (h w_max, w_max from the Jacobian at t = 0) vs "
                 "theory for an undamped oscillator\n"
              << fmt::format("{:<18} {:<8} {:<17} {:>10} {:>13} {:>15} {:>10}\n", "case", "backend",
                             "integrator", "stiffness", "last stable", "first unstable", "theory");
  }
  for (auto& [key, v] : groups) {
    std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    double last = kNaN, first_bad = kNaN;
    for (const auto& [dt, r] : v) {
      if ((*r)[cl] == "stable" || (*r)[cl] == "penetration") {
        if (std::isnan(first_bad)) last = std::stod((*r)[chw]);
      } else if (std::isnan(first_bad)) {
        first_bad = std::stod((*r)[chw]);
      }
    }
    const auto& r0 = *v.front().second;
    const double th = theory_limit(r0[ci]);
    std::cout << fmt::format("{:<18} {:<8} {:<17} {:>10} {:>13} {:>15} {:>10}\n", r0[cc], r0[cb],
                             r0[ci], r0[cs], std::isnan(last) ? "none" : num(last),
                             std::isnan(first_bad) ? "none" : num(first_bad),
                             th == 0.0 ? "unstable" : num(th));
  }
  // Tunnelling, contact and long runs: one line per run.
  bool header = false;
  for (const auto& r : t.rows) {
    if (r[ck] == "stiffness") continue;
    if (!header) {
      std::cout << "\n"
                << fmt::format("{:<14} {:<8} {:<17} {:>9} {:>8} {:>10} {:<14} {:>12} {:>12}\n",
                               "case", "backend", "integrator", "dt", "speed", "thickness", "class",
                               "max_pen", "energy_drift");
      header = true;
    }
    std::cout << fmt::format("{:<14} {:<8} {:<17} {:>9} {:>8} {:>10} {:<14} {:>12} {:>12}\n", r[cc],
                             r[cb], r[ci], r[cd], r[csp], r[cth], r[cl].substr(0, 40), r[cp],
                             r[ce]);
  }
  // Heat maps: class over (dt, stiffness) per integrator, or (speed, thickness) per backend.
  std::map<std::string, std::vector<const std::vector<std::string>*>> maps;
  for (const auto& r : t.rows)
    if (r[ck] == "stiffness")
      maps[r[cc] + "_" + r[ci]].push_back(&r);
    else if (r[ck] == "tunnelling")
      maps[r[cc] + "_" + r[cb] + "_" + r[ci]].push_back(&r);
  for (const auto& [name, rows] : maps) {
    const bool stiff = (*rows.front())[ck] == "stiffness";
    std::ostringstream dat;
    dat << "# x y class_code (0 stable, 1 penetration, 2 tunnelled, 3 energy blow-up, 4 NaN, "
           "5 error)\n";
    for (const auto* r : rows)
      dat << (stiff ? (*r)[cd] : (*r)[csp]) << ' ' << (stiff ? (*r)[cs] : (*r)[cth]) << ' '
          << class_code((*r)[cl]) << '\n';
    sweep::write_atomically(out / ("heat_" + name + ".dat"), dat.str());
    const fs::path script = out / ("heat_" + name + ".gp");
    std::ostringstream gp;
    gp << "set terminal svg size 800,600 dynamic\nset output 'heat_" << name << ".svg'\n"
       << "set logscale xy\nset xlabel '" << (stiff ? "dt (s)" : "ball speed (units/s)")
       << "'\nset ylabel '" << (stiff ? "stiffness" : "wall thickness") << "'\nset title '" << name
       << "' noenhanced\nset cbrange "
          "[0:5]\n"
       << "set palette defined (0 '#1a9850', 1 '#fee08b', 2 '#fdae61', 3 '#d73027', 4 "
          "'#67001f', 5 '#404040')\n"
       << "set cbtics ('stable' 0, 'penetration' 1, 'tunnelled' 2, 'unstable' 3, 'NaN' 4, "
          "'error' 5)\n"
       << "plot 'heat_" << name << ".dat' using 1:2:3 with points pt 5 ps 3 palette notitle\n";
    sweep::write_atomically(script, gp.str());
    if (sweep::run_gnuplot(script))
      spdlog::info("figure: {}", (out / ("heat_" + name + ".svg")).string());
  }
}

}  // namespace pinsim::stress
