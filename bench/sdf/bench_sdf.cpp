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

void row(const char* bench, const char* backend, const std::string& variant, std::size_t balls,
         int steps, int repeats, double med, const char* unit, uint64_t hash) {
  std::printf("%s,%s,%s,%zu,%d,%d,%.2f,%s,%016llx\n", bench, backend, variant.c_str(), balls, steps,
              repeats, med, unit, static_cast<unsigned long long>(hash));
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : std::string(PINSIM_CONFIG_DIR) + "/pinball.json";
  std::ifstream in(path);
  if (!in) {
    std::fprintf(stderr, "bench_sdf: cannot open %s\n", path.c_str());
    return 1;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  const json scene = json::parse(ss.str(), nullptr, true, true);
  const double dt = scene["time"]["dt"], duration = scene["time"]["duration"];
  double gx = 0.0, gy = 0.0;
  for (const auto& f : scene.value("forces", json::array()))
    if (f.value("type", "") == "gravity" && f.contains("params") && f["params"].contains("g")) {
      gx = f["params"]["g"][0];
      gy = f["params"]["g"][1];
    }
  const double radius = scene["particles"][0]["radius"];
  const double mass = scene["particles"][0].value("mass", 1.0);
  const json no_params = json::object();
  const json& sdf_params = scene.contains("backend") && scene["backend"].contains("params")
                               ? scene["backend"]["params"]
                               : no_params;
  json box2d_params = json::object();
  if (scene.contains("crosscheck") && scene["crosscheck"].contains("params") &&
      scene["crosscheck"]["params"].contains("box2d")) {
    box2d_params = scene["crosscheck"]["params"]["box2d"];
  } else {
    box2d_params["curve_segments"] = 256;
    box2d_params["rest_speed"] = params_for<SdfBackend>(sdf_params)["rest_speed"];
  }
  const int run_steps = static_cast<int>(std::lround(duration / dt));
  const std::vector<double> ball_x0 = {scene["particles"][0]["x"][0],
                                       scene["particles"][0]["x"][1]};

  if (argc > 2 && std::string(argv[2]) == "--trace") {
    // the scene's ball: its contacts (time, obstacle id) and state every 0.25 s
    BenchWorld<SdfBackend> w(scene, params_for<SdfBackend>(sdf_params), ball_x0, {0.0, 0.0}, radius,
                             nullptr, mass);
    pinsim_event_sink sink{&w, [](void* c, const pinsim_event* e) {
                             const auto* wp = static_cast<BenchWorld<SdfBackend>*>(c);
                             std::printf("event t=%.4f obstacle=%s vn %.3f -> %.3f\n", e->t,
                                         wp->be->field().obstacle(e->obstacle).id.c_str(),
                                         e->vn_before, e->vn_after);
                           }};
    for (int s = 0; s < run_steps; ++s) {
      w.step(dt, gx, gy, &sink);
      if (w.steps % static_cast<uint64_t>(std::lround(0.25 / dt)) == 0)
        std::printf("t=%.2f x=(%.9g, %.9g) v=(%.9g, %.9g)\n", w.t, w.x[0], w.x[1], w.v[0], w.v[1]);
    }
    const auto& st = w.be->stats();
    std::printf("steps %llu skipped %llu queries %llu contacts %llu cap_hits %llu\n",
                (unsigned long long)st.particle_steps, (unsigned long long)st.skipped,
                (unsigned long long)st.queries, (unsigned long long)st.contacts,
                (unsigned long long)st.cap_hits);
    return 0;
  }
  std::printf("benchmark,backend,variant,balls,steps,repeats,median,unit,state_hash\n");

  // 1. distance queries at random points and times on the table
  for (const long cells : {16384L, 65536L, 262144L, 0L}) {
    BenchWorld<SdfBackend> wq(scene, params_for<SdfBackend>(sdf_params, {{"grid_cells", cells}}),
                              {}, {}, radius);
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> ux(0.0, 0.5), uy(-0.05, 1.0), ut(0.0, duration);
    const std::size_t n = 1 << 20;
    std::vector<Vec2> pts(n);
    std::vector<double> ts(n);
    for (std::size_t i = 0; i < n; ++i) {
      pts[i] = Vec2(ux(rng), uy(rng));
      ts[i] = ut(rng);
    }
    for (int coherent = 0; coherent < 2; ++coherent) {
      if (coherent) {
        // points along paths as a simulation asks for them: 1 mm steps, times advancing by
        // 2e-4 s, restarting at a random point every 256 queries
        std::uniform_real_distribution<double> ua(0.0, 6.283185307179586);
        Vec2 p(0.25, 0.5), dir(1.0, 0.0);
        double t = 0.0;
        for (std::size_t i = 0; i < n; ++i) {
          if (i % 256 == 0) {
            p = Vec2(ux(rng), uy(rng));
            t = ut(rng);
            const double a = ua(rng);
            dir = Vec2(std::cos(a), std::sin(a));
          }
          p += 1e-3 * dir;
          if (p.x() < 0.0 || p.x() > 0.5) dir.x() = -dir.x();
          if (p.y() < -0.05 || p.y() > 1.0) dir.y() = -dir.y();
          t += 2e-4;
          pts[i] = p;
          ts[i] = t;
        }
      }
      std::vector<double> runs;
      double sink = 0.0;
      for (int rep = 0; rep < 7; ++rep) {
        const double t0 = cpu_ns();
        for (std::size_t i = 0; i < n; ++i) sink += wq.be->distance(pts[i], ts[i], nullptr);
        runs.push_back((cpu_ns() - t0) / static_cast<double>(n));
      }
      uint64_t h = 0;
      std::memcpy(&h, &sink, sizeof h);
      row("sdf_query", "sdf",
          (cells ? "grid_cells=" + std::to_string(cells) : std::string("brute_force")) +
              (coherent ? "_coherent_paths" : "_random_points"),
          0, 0, 7, median(runs), "ns/query", h);
    }
  }
  if (argc > 2 && std::string(argv[2]) == "--queries") return 0;

  // 2. ns per ball-step on both backends, same scene, dt and gravity: the scene's own ball
  // (plunger launch, flippers) for the full run, and 100 / 10,000 balls dropped at random
  // into the playfield. Repeats alternate between the backends, so a change of machine
  // load falls on both.
  struct Case {
    const char* name;
    std::size_t balls;
    int steps;  ///< 0: the scene's whole run
    int repeats;
    bool pairs;  ///< ball-ball contacts on
  };
  struct Result {
    std::string name;
    std::size_t balls;
    int steps;
    double sdf, box2d, one_query;
    std::string note;
  };
  std::vector<Result> results;
  BenchWorld<SdfBackend> probe(scene, params_for<SdfBackend>(sdf_params), {}, {}, radius);
  for (const Case c :
       {Case{"scene_ball_full_run", 1, 0, 5, false}, Case{"random_drop", 100, 3000, 5, false},
        Case{"random_drop", 10000, 60, 3, false},
        Case{"random_drop_ball_contacts", 100, 3000, 5, true}}) {
    std::vector<double> x0 = ball_x0, v0 = {0.0, 0.0};
    if (c.balls > 1) {
      x0.clear();
      v0.clear();
      std::mt19937_64 rng(42);
      std::uniform_real_distribution<double> ux(0.05, 0.40), uy(0.35, 0.95), uv(-1.0, 1.0);
      for (std::size_t i = 0; i < c.balls; ++i) {
        // drawn again until clear of every obstacle (and inside the table)
        double px = 0.0, py = 0.0;
        do {
          px = ux(rng);
          py = uy(rng);
        } while (probe.be->distance(Vec2(px, py), 0.0, nullptr) < radius + 1e-3);
        x0.push_back(px);
        x0.push_back(py);
        v0.push_back(uv(rng));
        v0.push_back(uv(rng));
      }
    }
    const double ball_mass = c.balls == 1 ? mass : 1.0;  // the scene's own ball: its mass
    const json contacts = c.pairs ? json{{"particles", true}, {"restitution", 0.9}} : json(nullptr);
    const int steps = c.steps ? c.steps : run_steps;
    const double ball_steps = static_cast<double>(steps) * static_cast<double>(c.balls);
    std::vector<double> sdf_runs, box2d_runs;
    uint64_t sdf_hash = 0, box2d_hash = 0;
    double one_query = 0.0;
    std::string note;
    for (int rep = 0; rep < c.repeats; ++rep) {
      {
        BenchWorld<SdfBackend> wb(scene, params_for<SdfBackend>(sdf_params), x0, v0, radius,
                                  contacts, ball_mass);
        const double t0 = cpu_ns();
        for (int s = 0; s < steps; ++s) wb.step(dt, gx, gy);
        sdf_runs.push_back((cpu_ns() - t0) / ball_steps);
        sdf_hash = wb.hash();
        const auto& st = wb.be->stats();
        one_query = static_cast<double>(st.skipped) / static_cast<double>(st.particle_steps);
      }
      if (!note.empty()) continue;
      try {
        BenchWorld<Box2dBackend> wb(scene, params_for<Box2dBackend>(box2d_params), x0, v0, radius,
                                    contacts, ball_mass);
        const double t0 = cpu_ns();
        for (int s = 0; s < steps; ++s) wb.step(dt, gx, gy);
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
    results.push_back({c.name, c.balls, steps, median(sdf_runs), b2, one_query, note});
  }

  std::printf(
      "\ncase,balls,steps,sdf_ns_per_ball_step,box2d_ns_per_ball_step,"
      "ratio_box2d_over_sdf,sdf_one_query_steps,note\n");
  for (const Result& r : results)
    std::printf("%s,%zu,%d,%.2f,%.2f,%.2f,%.3f,%s\n", r.name.c_str(), r.balls, r.steps, r.sdf,
                r.box2d, r.box2d / r.sdf, r.one_query, r.note.c_str());
  return 0;
}
