// bench_sdf: SDF query time on configs/pinball.json, and ns per ball-step of the sdf and
// box2d backends on the same scenes in one run, with the ratio box2d / sdf.
// Prints CSV: benchmark,backend,variant,balls,steps,repeats,median,unit,state_hash
// then a comparison table: case,balls,steps,sdf_ns,box2d_ns,ratio_box2d_over_sdf.
// Usage: bench_sdf [scene.json [--trace | --queries]]   (default: configs/pinball.json)
// --trace prints the scene ball's contacts; --queries runs only the distance-query part.
// Box2D runs with the scene's crosscheck.params.box2d if it has them, else with
// curve_segments 256 (the pinball top) and the sdf backend's rest_speed.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "bench_world.hpp"
#include "box2d_backend.hpp"
#include "sdf_backend.hpp"

using namespace pinsim;
using namespace pinsim::bench;
using nlohmann::json;
using pinsim::box2d::Box2dBackend;
using pinsim::sdf::SdfBackend;

namespace {

/// What the benchmarks take from the scene file.
struct BenchScene {
  json scene;
  double dt = 0.0, duration = 0.0;
  double gx = 0.0, gy = 0.0;    ///< the gravity plugin's g, if any
  double radius = 0.0;          ///< particles[0]'s radius: every ball's
  double mass = 1.0;            ///< particles[0]'s mass: the scene ball's
  std::vector<double> ball_x0;  ///< particles[0]'s position
  int run_steps = 0;            ///< steps of the scene's whole run
  json sdf_params;              ///< the scene's backend params
  json box2d_params;            ///< crosscheck.params.box2d, else curve_segments and rest_speed
};

/// One ball-step case: balls dropped at random (or the scene's own ball) for some steps.
struct Case {
  const char* name;
  std::size_t balls;
  int steps;  ///< 0: the scene's whole run
  int repeats;
  bool pairs;  ///< ball-ball contacts on
};

/// One case's figures on both backends.
struct Result {
  std::string name;
  std::size_t balls;
  int steps;
  double sdf, box2d, one_query;
  std::string note;
};

/// Distance queries: points and their times.
struct Queries {
  std::vector<Vec2> pts;
  std::vector<double> ts;
};

/// The table's query region: x, y on the playfield, t over the run.
struct QueryRegion {
  std::uniform_real_distribution<double> ux, uy, ut;
};

void row(const char* bench, const char* backend, const std::string& variant, std::size_t balls,
         int steps, int repeats, double med, const char* unit, uint64_t hash) {
  std::printf("%s,%s,%s,%zu,%d,%d,%.2f,%s,%016llx\n", bench, backend, variant.c_str(), balls, steps,
              repeats, med, unit, static_cast<unsigned long long>(hash));
  std::fflush(stdout);
}

// Reads the scene file (JSON with comments); nothing if it cannot be opened.
std::optional<json> read_scene_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) return std::nullopt;
  std::stringstream ss;
  ss << in.rdbuf();
  return json::parse(ss.str(), nullptr, true, true);
}

// The time step, gravity, ball and backend parameters the benchmarks use.
BenchScene bench_scene(json scene) {
  BenchScene b;
  b.scene = std::move(scene);
  const json& s = b.scene;
  b.dt = s["time"]["dt"];
  b.duration = s["time"]["duration"];
  for (const auto& f : s.value("forces", json::array()))
    if (f.value("type", "") == "gravity" && f.contains("params") && f["params"].contains("g")) {
      b.gx = f["params"]["g"][0];
      b.gy = f["params"]["g"][1];
    }
  b.radius = s["particles"][0]["radius"];
  b.mass = s["particles"][0].value("mass", 1.0);
  b.sdf_params = s.contains("backend") && s["backend"].contains("params") ? s["backend"]["params"]
                                                                          : json::object();
  b.box2d_params = json::object();
  if (s.contains("crosscheck") && s["crosscheck"].contains("params") &&
      s["crosscheck"]["params"].contains("box2d")) {
    b.box2d_params = s["crosscheck"]["params"]["box2d"];
  } else {
    b.box2d_params["curve_segments"] = 256;
    b.box2d_params["rest_speed"] = params_for<SdfBackend>(b.sdf_params)["rest_speed"];
  }
  b.run_steps = static_cast<int>(std::lround(b.duration / b.dt));
  b.ball_x0 = {s["particles"][0]["x"][0], s["particles"][0]["x"][1]};
  return b;
}

// --trace: the scene's ball on the sdf backend, its contacts (time, obstacle id) and state
// every 0.25 s, then the backend's counters.
void trace_scene_ball(const BenchScene& b) {
  BenchWorld<SdfBackend> w(b.scene, params_for<SdfBackend>(b.sdf_params), b.ball_x0, {0.0, 0.0},
                           b.radius, nullptr, b.mass);
  pinsim_event_sink sink{&w, [](void* c, const pinsim_event* e) {
                           const auto* wp = static_cast<BenchWorld<SdfBackend>*>(c);
                           std::printf("event t=%.4f obstacle=%s vn %.3f -> %.3f\n", e->t,
                                       wp->be->field().obstacle(e->obstacle).id.c_str(),
                                       e->vn_before, e->vn_after);
                         }};
  for (int s = 0; s < b.run_steps; ++s) {
    w.step(b.dt, b.gx, b.gy, &sink);
    if (w.steps % static_cast<uint64_t>(std::lround(0.25 / b.dt)) == 0)
      std::printf("t=%.2f x=(%.9g, %.9g) v=(%.9g, %.9g)\n", w.t, w.x[0], w.x[1], w.v[0], w.v[1]);
  }
  const auto& st = w.be->stats();
  std::printf("steps %llu skipped %llu queries %llu contacts %llu cap_hits %llu\n",
              (unsigned long long)st.particle_steps, (unsigned long long)st.skipped,
              (unsigned long long)st.queries, (unsigned long long)st.contacts,
              (unsigned long long)st.cap_hits);
}

// Points uniformly over the region at uniform times.
void random_queries(std::mt19937_64& rng, QueryRegion& region, Queries& q) {
  for (std::size_t i = 0; i < q.pts.size(); ++i) {
    q.pts[i] = Vec2(region.ux(rng), region.uy(rng));
    q.ts[i] = region.ut(rng);
  }
}

// Points along paths as a simulation asks for them: 1 mm steps, times advancing by 2e-4 s,
// restarting at a random point every 256 queries.
void coherent_queries(std::mt19937_64& rng, QueryRegion& region, Queries& q) {
  std::uniform_real_distribution<double> ua(0.0, 6.283185307179586);
  Vec2 p(0.25, 0.5), dir(1.0, 0.0);
  double t = 0.0;
  for (std::size_t i = 0; i < q.pts.size(); ++i) {
    if (i % 256 == 0) {
      p = Vec2(region.ux(rng), region.uy(rng));
      t = region.ut(rng);
      const double a = ua(rng);
      dir = Vec2(std::cos(a), std::sin(a));
    }
    p += 1e-3 * dir;
    if (p.x() < 0.0 || p.x() > 0.5) dir.x() = -dir.x();
    if (p.y() < -0.05 || p.y() > 1.0) dir.y() = -dir.y();
    t += 2e-4;
    q.pts[i] = p;
    q.ts[i] = t;
  }
}

// Runs the queries 7 times; prints the median ns per query with the bits of the sum of the
// distances as its hash.
void time_queries(const SdfBackend& be, const Queries& q, const std::string& variant) {
  const std::size_t n = q.pts.size();
  std::vector<double> runs;
  double sink = 0.0;
  for (int rep = 0; rep < 7; ++rep) {
    const double t0 = cpu_ns();
    for (std::size_t i = 0; i < n; ++i) sink += be.distance(q.pts[i], q.ts[i], nullptr);
    runs.push_back((cpu_ns() - t0) / static_cast<double>(n));
  }
  uint64_t h = 0;
  std::memcpy(&h, &sink, sizeof h);
  row("sdf_query", "sdf", variant, 0, 0, 7, median(runs), "ns/query", h);
}

// 1. distance queries at random points and times on the table, and along paths, for
// several grid sizes and without the grid.
void bench_queries(const BenchScene& b) {
  for (const long cells : {16384L, 65536L, 262144L, 0L}) {
    BenchWorld<SdfBackend> wq(
        b.scene, params_for<SdfBackend>(b.sdf_params, {{"grid_cells", cells}}), {}, {}, b.radius);
    std::mt19937_64 rng(1);
    QueryRegion region{std::uniform_real_distribution<double>(0.0, 0.5),
                       std::uniform_real_distribution<double>(-0.05, 1.0),
                       std::uniform_real_distribution<double>(0.0, b.duration)};
    Queries q{std::vector<Vec2>(1 << 20), std::vector<double>(1 << 20)};
    random_queries(rng, region, q);
    const std::string grid =
        cells ? "grid_cells=" + std::to_string(cells) : std::string("brute_force");
    time_queries(*wq.be, q, grid + "_random_points");
    coherent_queries(rng, region, q);
    time_queries(*wq.be, q, grid + "_coherent_paths");
  }
}

// Starting positions and velocities of `balls` balls dropped at random into the playfield,
// each drawn again until clear of every obstacle (and inside the table).
void drop_balls(const SdfBackend& probe, double radius, std::size_t balls, std::vector<double>& x0,
                std::vector<double>& v0) {
  x0.clear();
  v0.clear();
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> ux(0.05, 0.40), uy(0.35, 0.95), uv(-1.0, 1.0);
  for (std::size_t i = 0; i < balls; ++i) {
    double px = 0.0, py = 0.0;
    do {
      px = ux(rng);
      py = uy(rng);
    } while (probe.distance(Vec2(px, py), 0.0, nullptr) < radius + 1e-3);
    x0.push_back(px);
    x0.push_back(py);
    v0.push_back(uv(rng));
    v0.push_back(uv(rng));
  }
}

// One case on both backends, repeats alternating between them so that a change of machine
// load falls on both; prints a row per backend (box2d's only if it ran).
Result run_case(const BenchScene& b, const SdfBackend& probe, const Case& c) {
  std::vector<double> x0 = b.ball_x0, v0 = {0.0, 0.0};
  if (c.balls > 1) drop_balls(probe, b.radius, c.balls, x0, v0);
  const double ball_mass = c.balls == 1 ? b.mass : 1.0;  // the scene's own ball: its mass
  const json contacts = c.pairs ? json{{"particles", true}, {"restitution", 0.9}} : json(nullptr);
  const int steps = c.steps ? c.steps : b.run_steps;
  const double ball_steps = static_cast<double>(steps) * static_cast<double>(c.balls);
  std::vector<double> sdf_runs, box2d_runs;
  uint64_t sdf_hash = 0, box2d_hash = 0;
  double one_query = 0.0;
  std::string note;
  for (int rep = 0; rep < c.repeats; ++rep) {
    {
      BenchWorld<SdfBackend> wb(b.scene, params_for<SdfBackend>(b.sdf_params), x0, v0, b.radius,
                                contacts, ball_mass);
      const double t0 = cpu_ns();
      for (int s = 0; s < steps; ++s) wb.step(b.dt, b.gx, b.gy);
      sdf_runs.push_back((cpu_ns() - t0) / ball_steps);
      sdf_hash = wb.hash();
      const auto& st = wb.be->stats();
      one_query = static_cast<double>(st.skipped) / static_cast<double>(st.particle_steps);
    }
    if (!note.empty()) continue;
    try {
      BenchWorld<Box2dBackend> wb(b.scene, params_for<Box2dBackend>(b.box2d_params), x0, v0,
                                  b.radius, contacts, ball_mass);
      const double t0 = cpu_ns();
      for (int s = 0; s < steps; ++s) wb.step(b.dt, b.gx, b.gy);
      box2d_runs.push_back((cpu_ns() - t0) / ball_steps);
      box2d_hash = wb.hash();
    } catch (const std::exception& e) {
      note = std::string("box2d failed: ") + e.what();
    }
  }
  row("ball_step", "sdf", c.name, c.balls, steps, c.repeats, median(sdf_runs), "ns/ball-step",
      sdf_hash);
  const double b2 = box2d_runs.empty() ? NAN : median(box2d_runs);
  if (!box2d_runs.empty())
    row("ball_step", "box2d", c.name, c.balls, steps, static_cast<int>(box2d_runs.size()), b2,
        "ns/ball-step", box2d_hash);
  return {c.name, c.balls, steps, median(sdf_runs), b2, one_query, note};
}

// 2. ns per ball-step on both backends, same scene, dt and gravity: the scene's own ball
// (plunger launch, flippers) for the full run, and 100 / 10,000 balls dropped at random
// into the playfield.
std::vector<Result> bench_ball_steps(const BenchScene& b) {
  std::vector<Result> results;
  BenchWorld<SdfBackend> probe(b.scene, params_for<SdfBackend>(b.sdf_params), {}, {}, b.radius);
  for (const Case c :
       {Case{"scene_ball_full_run", 1, 0, 5, false}, Case{"random_drop", 100, 3000, 5, false},
        Case{"random_drop", 10000, 60, 3, false},
        Case{"random_drop_ball_contacts", 100, 3000, 5, true}})
    results.push_back(run_case(b, *probe.be, c));
  return results;
}

// The comparison table: per case both backends' figures and their ratio.
void print_comparison(const std::vector<Result>& results) {
  std::printf(
      "\ncase,balls,steps,sdf_ns_per_ball_step,box2d_ns_per_ball_step,"
      "ratio_box2d_over_sdf,sdf_one_query_steps,note\n");
  for (const Result& r : results)
    std::printf("%s,%zu,%d,%.2f,%.2f,%.2f,%.3f,%s\n", r.name.c_str(), r.balls, r.steps, r.sdf,
                r.box2d, r.box2d / r.sdf, r.one_query, r.note.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : std::string(PINSIM_CONFIG_DIR) + "/pinball.json";
  const std::string mode = argc > 2 ? argv[2] : "";
  std::optional<json> scene = read_scene_file(path);
  if (!scene) {
    std::fprintf(stderr, "bench_sdf: cannot open %s\n", path.c_str());
    return 1;
  }
  const BenchScene b = bench_scene(std::move(*scene));
  if (mode == "--trace") {
    trace_scene_ball(b);
    return 0;
  }
  std::printf("benchmark,backend,variant,balls,steps,repeats,median,unit,state_hash\n");
  bench_queries(b);
  if (mode == "--queries") return 0;
  print_comparison(bench_ball_steps(b));
  return 0;
}
