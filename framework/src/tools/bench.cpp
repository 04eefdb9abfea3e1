#include "tools/bench.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

#include "core/format.hpp"
#include "core/json_read.hpp"
#include "core/simulation.hpp"
#include "tools/bench_answer.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace pinsim::bench {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Errors at or below this are rounding, not truncation: they carry no convergence order.
constexpr double kRoundingError = 1e-13;

/// One point of the sweep.
struct Point {
  std::size_t index;
  std::size_t case_index;
  json backend;  ///< {"name":..., "params":...} or null (the scene's)
  std::string integrator;
  double dt;
};

struct Case {
  std::string name;
  json doc;  ///< the scene document
  fs::path base;
  json answer;        ///< closed form spec, or null
  json reference;     ///< {"integrator", "dt", "sample_every"} or null
  std::string where;  ///< "bench.json: cases[2]", for the answer's messages
};

std::vector<std::pair<std::string, json>> settings(const Point& p, bool timing) {
  std::vector<std::pair<std::string, json>> set = {
      {"time.dt", p.dt},
      {"integrator", p.integrator},
      {"checks.energy_every", timing ? json(1000000000) : json(1)},
      {"checks.energy_blowup", 1e300},
      {"checks.kinetic_growth", 0}};
  if (!p.backend.is_null()) set.emplace_back("backend", p.backend);
  return set;
}

/// o.name if it is a string, else `def` (a label for the log and CSV; the scene's own
/// parsing refuses a backend without a proper name, naming the file and path).
std::string name_or(const json& o, const std::string& def) {
  if (o.is_string()) return o.get<std::string>();
  const auto it = o.is_object() ? o.find("name") : o.end();
  return it != o.end() && it->is_string() ? it->get<std::string>() : def;
}

std::string backend_name(const json& b, const json& doc) {
  if (b.is_object()) return name_or(b, "?");
  if (doc.contains("backend")) return name_or(doc["backend"], "none");
  return "none";
}

/// Positions of all particles at the sample times k * every, k = 1.. (reference runs).
using Samples = std::vector<Eigen::Matrix2Xd>;

Samples reference_samples(const Case& c, const json& backend, PluginLoader& loader) {
  const json& r = c.reference;
  Point p{0, 0, backend, r.value("integrator", std::string("rk4")), r.value("dt", 1e-5)};
  const Scene scene = sweep::make_scene(c.doc, settings(p, true), c.name + " (reference)", c.base);
  const double every = r.value("sample_every", scene.duration / 10.0);
  Simulation sim(scene, loader);
  Samples out;
  const uint64_t N = scene.steps();
  const double per = every / p.dt;
  for (uint64_t n = 1; n <= N; ++n) {
    sim.step();
    const double k = static_cast<double>(n) / per;
    if (std::abs(k - std::round(k)) < 1e-9 * static_cast<double>(n) && std::round(k) >= 1)
      out.push_back(sim.state().x);
  }
  spdlog::info("{}: reference run ({}, dt = {}) on {}: {} samples", c.name, p.integrator, p.dt,
               backend_name(backend, c.doc), out.size());
  return out;
}

struct Result {
  std::string status = "ok";
  uint64_t steps = 0;
  double t_med = kInf, t_min = kInf, err_final = kInf, err_max = kInf, drift = kInf;
  uint64_t force_evals = 0, jac_evals = 0, contacts = 0;
};

Result run_point(const Case& c, const Point& p, int repeats, PluginLoader& loader,
                 const Samples* ref) {
  Result res;
  const Scene acc = sweep::make_scene(c.doc, settings(p, false), c.name, c.base);
  // No step, no measurement: error 0 and time 0 would read as the sweep's best point.
  if (acc.steps() == 0)
    throw InputError(c.where + ".dt: " + num(p.dt) + " s makes no step in the scene's " +
                     num(acc.duration) + " s (a dt must be at most the duration)");
  std::optional<Answer> answer;
  if (!c.answer.is_null()) answer.emplace(c.answer, acc.initial_state(), c.where + ".answer");
  const double every =
      ref ? c.reference.value("sample_every", acc.duration / 10.0) : 0.0;  // reference samples
  // Accuracy run (untimed): error every step against the closed form, or at the reference
  // samples; energy drift checked every step.
  try {
    Simulation sim(acc, loader);
    const uint64_t N = acc.steps();
    double emax = 0.0, efin = 0.0;
    std::size_t k = 0;
    for (uint64_t n = 1; n <= N; ++n) {
      sim.step();
      res.contacts += sim.events().size();
      double e = -1.0;
      if (answer) {
        e = (sim.state().x.col(static_cast<Eigen::Index>(answer->particle())) -
             answer->position(sim.state().t))
                .norm();
      } else if (ref) {
        const double kk = sim.state().t / every;
        if (std::abs(kk - std::round(kk)) < 1e-6 && std::round(kk) >= 1 && k < ref->size()) {
          e = ((sim.state().x - (*ref)[k]).colwise().norm()).maxCoeff();
          ++k;
        }
      }
      if (e >= 0.0) {
        emax = std::max(emax, e);
        efin = e;
      }
    }
    if (ref && k != ref->size())
      throw InputError(c.name + ": dt = " + num(p.dt) + " does not divide the reference's " +
                       "sample_every = " + num(every));
    res.err_max = emax;
    res.err_final = efin;
    res.drift = sim.energy_complete() ? sim.max_energy_drift() : std::nan("");
    res.steps = N;
    res.force_evals = sim.force_evaluations();
    res.jac_evals = sim.jacobian_evaluations();
  } catch (const NumericError& e) {
    res.status = fmt::format("numeric error at step {} particle {}", e.step, e.particle);
    return res;
  }
  // Timed runs: only the step loop, no checks beyond the per-step NaN test.
  const Scene timed = sweep::make_scene(c.doc, settings(p, true), c.name, c.base);
  std::vector<double> times;
  for (int r = 0; r < std::max(1, repeats); ++r) {
    Simulation sim(timed, loader);
    const uint64_t N = timed.steps();
    const auto t0 = std::chrono::steady_clock::now();
    for (uint64_t n = 0; n < N; ++n) {
      sim.step();
    }
    times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(times.begin(), times.end());
  res.t_min = times.front();
  const std::size_t m = times.size();
  res.t_med = m % 2 ? times[m / 2] : 0.5 * (times[m / 2 - 1] + times[m / 2]);
  return res;
}

/// Checks case `ci` of the config (its keys, exactly one of answer and reference, their
/// keys and types) and reads it.
Case read_case(const sweep::Config& cfg, const json& cj, std::size_t ci,
               const sweep::CaseAt& where) {
  const std::string& cw = where.where;
  const Loc& at = where.at;
  check_keys(cj, {"name", "scene", "answer", "reference", "dt", "integrators", "backends"}, at);
  Case c;
  c.name = read_string_or(cj, "name", "case" + std::to_string(ci), at);
  c.where = cw;
  if (!cj.contains("scene")) throw InputError(cw + ".scene: required");
  c.doc = sweep::scene_doc(cfg, cj["scene"], c.base);
  c.answer = cj.value("answer", json());
  c.reference = cj.value("reference", json());
  if (c.answer.is_null() == c.reference.is_null())
    throw InputError(cw + ": give exactly one of \"answer\" (closed form) or \"reference\"");
  if (!c.answer.is_null()) require_object(c.answer, at / "answer");
  if (!c.reference.is_null()) require_object(c.reference, at / "reference");
  // a misspelt optional key (damping_ratio, floor, ...) would silently change the answer
  if (c.answer.is_object()) {
    const std::string type = read_string_or(c.answer, "type", "", at / "answer");
    if (type == "projectile")
      check_keys(c.answer, {"type", "particle", "g"}, at / "answer");
    else if (type == "harmonic")
      check_keys(c.answer, {"type", "particle", "omega", "damping_ratio", "center"}, at / "answer");
    else if (type == "bouncing_ball")
      check_keys(c.answer, {"type", "particle", "floor", "g", "restitution"}, at / "answer");
    else if (type == "ball_in_box")
      check_keys(c.answer, {"type", "particle", "min", "max"}, at / "answer");
  }
  if (c.reference.is_object()) {
    check_keys(c.reference, {"integrator", "dt", "sample_every"}, at / "reference");
    // read later with these defaults: their types are checked here, where the path is known
    read_string_or(c.reference, "integrator", "rk4", at / "reference");
    read_number_or(c.reference, "dt", 1e-5, at / "reference");
    read_number_or(c.reference, "sample_every", 1.0, at / "reference");
  }
  return c;
}

/// What a bench config asks for: its cases, the points crossing their axes (backends
/// outermost, dt innermost) and the timed runs per point.
struct Plan {
  std::vector<Case> cases;
  std::vector<Point> points;
  int repeats = 0;
};

/// Reads and checks the whole config; InputError names what is wrong and where.
Plan read_plan(const sweep::Config& cfg, const Options& o) {
  const json& d = cfg.doc;
  const std::string where = cfg.file.string();
  const json& cases_j = sweep::cases(cfg);
  check_keys(d, {"$schema", "description", "cases", "integrators", "backends", "dt", "repeats"},
             {where, ""});
  Plan plan;
  plan.repeats = o.repeats >= 0 ? o.repeats
                                : static_cast<int>(std::min<uint64_t>(
                                      read_count_or(d, "repeats", 3, {where, ""}), 1000000));
  for (std::size_t ci = 0; ci < cases_j.size(); ++ci) {
    const json& cj = cases_j[ci];
    Case c = read_case(cfg, cj, ci, sweep::case_at(cfg, ci));
    const sweep::Axes ax = sweep::case_axes(cfg, cj, c.where);
    for (const json& b : ax.backends)
      for (const std::string& in : ax.integrators)
        for (double dt : ax.dts)
          plan.points.push_back({plan.points.size(), plan.cases.size(), b, in, dt});
    plan.cases.push_back(std::move(c));
  }
  return plan;
}

/// What makes shards parts of one sweep: the config, every case's scene, the options.
std::string inputs_of(const sweep::Config& cfg, const Plan& plan) {
  std::vector<const json*> scenes;
  for (const Case& c : plan.cases) scenes.push_back(&c.doc);
  return sweep::sweep_inputs("bench", cfg, "\nrepeats=" + std::to_string(plan.repeats), scenes);
}

/// Runs the points of a plan, each to its CSV row and a log line; a reference run is made
/// once per case and backend and kept for the case's other points.
class PointRunner {
 public:
  explicit PointRunner(const Plan& plan) : plan_(plan), loader_(plugin_search_dirs()) {}

  std::vector<std::string> operator()(std::size_t i) {
    const Point& p = plan_.points[i];
    const Case& c = plan_.cases[p.case_index];
    const std::string bname = backend_name(p.backend, c.doc);
    const Samples* ref = reference(p, c);
    Result r;
    try {
      r = run_point(c, p, plan_.repeats, loader_, ref);
    } catch (const PluginError& e) {
      r.status = std::string("plugin error: ") + e.what();
    }
    if (r.status != "ok") failed_ = true;
    std::replace(r.status.begin(), r.status.end(), ',', ';');
    spdlog::info("[{}/{}] {} {} {} dt={} err_max={} time={}s {}", p.index + 1, plan_.points.size(),
                 c.name, bname, p.integrator, p.dt, num(r.err_max), num(r.t_med), r.status);
    return {std::to_string(p.index),
            c.name,
            c.answer.is_null() ? "reference" : c.answer.value("type", "?"),
            bname,
            p.integrator,
            num(p.dt),
            std::to_string(r.steps),
            std::to_string(plan_.repeats),
            num(r.t_med),
            num(r.t_min),
            num(r.err_final),
            num(r.err_max),
            num(r.drift),
            std::to_string(r.force_evals),
            std::to_string(r.jac_evals),
            std::to_string(r.contacts),
            r.status};
  }

  /// Some point ran into a numeric or plugin error.
  bool failed() const { return failed_; }

 private:
  /// The reference samples point p compares with; nullptr for a case with a closed form.
  const Samples* reference(const Point& p, const Case& c) {
    if (c.reference.is_null()) return nullptr;
    auto key = std::make_pair(p.case_index, p.backend.dump());
    if (!refs_.count(key)) refs_[key] = reference_samples(c, p.backend, loader_);
    return &refs_[key];
  }

  const Plan& plan_;
  PluginLoader loader_;
  std::map<std::pair<std::size_t, std::string>, Samples> refs_;
  bool failed_ = false;
};

}  // namespace

const std::vector<std::string>& columns() {
  static const std::vector<std::string> c = {
      "point",        "case",        "answer",         "backend",    "integrator",  "dt",
      "steps",        "repeats",     "time_median_s",  "time_min_s", "error_final", "error_max",
      "energy_drift", "force_evals", "jacobian_evals", "contacts",   "status"};
  return c;
}

int run(const Options& o) {
  const sweep::Config cfg = sweep::load_config(o.config);
  const Plan plan = read_plan(cfg, o);
  if (o.check_only) return 0;
  PointRunner points(plan);
  sweep::Sweep sw;
  sw.tool = "bench";
  sw.columns = columns();
  sw.points = plan.points.size();
  sw.inputs = inputs_of(cfg, plan);
  sw.run_point = std::ref(points);
  sw.report = report;
  const int sig = sweep::drive(sw, o.shard, o.out, cfg.file.string(), o.resume);
  return sweep::exit_code(sig, points.failed() ? 1 : 0);
}

void report(const sweep::Table& t, const fs::path& out) {
  const auto cc = t.col("case"), cb = t.col("backend"), ci = t.col("integrator"), cd = t.col("dt"),
             cf = t.col("error_final"), cm = t.col("error_max"), ct = t.col("time_median_s"),
             cs = t.col("status");
  // series -> (dt, err_final, err_max, time)
  std::map<std::string, std::map<std::string, std::vector<std::array<double, 4>>>> series;
  for (const auto& r : t.rows) {
    if (r[cs] != "ok") continue;
    series[r[cc]][r[ci] + " / " + r[cb]].push_back(
        {std::stod(r[cd]), std::stod(r[cf]), std::stod(r[cm]), std::stod(r[ct])});
  }
  std::cout << "\nobserved convergence order (least-squares slope of log error vs log dt)\n";
  std::cout << fmt::format("{:<22} {:<34} {:>12} {:>12} {:>14}\n", "case", "integrator / backend",
                           "order(max)", "order(final)", "best err_max");
  bool any_exact = false, any_short = false;
  for (auto& [cname, ss] : series) {
    for (auto& [sname, pts] : ss) {
      std::vector<double> dt, ef, em;
      double best = kInf;
      for (const auto& p : pts) {
        dt.push_back(p[0]);
        // Errors at rounding level carry no order information.
        ef.push_back(p[1] > kRoundingError ? p[1] : std::nan(""));
        em.push_back(p[2] > kRoundingError ? p[2] : std::nan(""));
        best = std::min(best, p[2]);
      }
      // An order needs two dt with errors above rounding level: "exact" when every error is
      // at rounding level (the method integrates this case exactly), "-" when fewer than two
      // dt were run.
      const auto order = [&](const std::vector<double>& e) {
        const double slope = sweep::loglog_slope(dt, e);
        if (std::isfinite(slope)) return fmt::format("{:.3f}", slope);
        const bool exact = std::none_of(e.begin(), e.end(), [](double x) { return x == x; });
        (exact && dt.size() >= 2 ? any_exact : any_short) = true;
        return std::string(exact && dt.size() >= 2 ? "exact" : "-");
      };
      std::cout << fmt::format("{:<22} {:<34} {:>12} {:>12} {:>14.3e}\n", cname, sname, order(em),
                               order(ef), best);
    }
    // Work-precision figure: error on x, median time on y, log-log.
    const fs::path script = out / ("work_precision_" + cname + ".gp");
    std::ostringstream gp;
    gp << "set terminal svg size 900,600 dynamic\nset output 'work_precision_" << cname
       << ".svg'\nset logscale xy\nset format x '10^{%L}'\nset format y '10^{%L}'\n"
       << "set xlabel 'largest position error over the trajectory'\n"
       << "set ylabel 'median wall time per run (s)'\nset title 'work-precision: " << cname
       << "' noenhanced\nset key outside right\nset grid\nplot ";
    int k = 0;
    for (auto& [sname, pts] : ss) {
      std::string file = "wp_" + cname + "_" + std::to_string(k) + ".dat";
      std::ostringstream dat;
      dat << "# " << sname << ": error_max time_median_s dt\n";
      for (const auto& p : pts)
        if (p[2] > 0.0 && std::isfinite(p[2]) && p[3] > 0.0)
          dat << num(p[2]) << ' ' << num(p[3]) << ' ' << num(p[0]) << '\n';
      sweep::write_atomically(out / file, dat.str());
      gp << (k ? ", \\\n     " : "") << "'" << file << "' using 1:2 with linespoints title '"
         << sname << "' noenhanced";  // names hold '_', not subscripts
      ++k;
    }
    gp << "\n";
    sweep::write_atomically(script, gp.str());
    if (sweep::run_gnuplot(script))
      spdlog::info("figure: {}", (out / ("work_precision_" + cname + ".svg")).string());
  }
  if (any_exact)
    std::cout << "exact: the error is at rounding level (<= " << num(kRoundingError)
              << ") at every dt: the method is exact for this case, so it has no order\n";
  if (any_short) std::cout << "-: fewer than two dt with errors above rounding level\n";
}

}  // namespace pinsim::bench
