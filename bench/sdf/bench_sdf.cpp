// bench_sdf: SDF query time and ns per ball-step on configs/pinball.json.
// Prints CSV: benchmark,variant,balls,repeats,median,unit,state_hash
// Usage: bench_sdf [scene.json]   (default: the source tree's configs/pinball.json)
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "sdf_backend.hpp"

using namespace pinsim;
using namespace pinsim::sdf;
using nlohmann::json;
/// Thread CPU time, so that a busy shared machine does not inflate the figures.
struct Clock {
  struct time_point {
    double ns;
    std::chrono::duration<double, std::nano> operator-(const time_point& o) const {
      return std::chrono::duration<double, std::nano>(ns - o.ns);
    }
  };
  static time_point now() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return {1e9 * static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec)};
  }
};

namespace {

json params_for(const json& scene, const json& over = json::object()) {
  json p = json::object();
  for (const auto& d : SdfBackend::info().params) p[d.name] = d.def[0];
  if (scene.contains("backend") && scene["backend"].contains("params"))
    for (const auto& [k, v] : scene["backend"]["params"].items()) p[k] = v;
  for (const auto& [k, v] : over.items()) p[k] = v;
  return p;
}

json backend_scene(const json& s) {
  json b = json::object();
  for (const char* k : {"obstacles", "inputs", "contacts"})
    if (s.contains(k)) b[k] = s[k];
  return b;
}

struct World {
  std::vector<double> x, v, w, r;
  std::unique_ptr<SdfBackend> be;
  double t = 0.0;
  uint64_t events = 0;

  World(const json& scene, const json& params, std::vector<double> x0, std::vector<double> v0,
        double radius, const json& contacts = nullptr)
      : x(std::move(x0)), v(std::move(v0)), w(x.size() / 2, 1.0), r(x.size() / 2, radius) {
    pinsim_state_view sv{w.size(), 0.0, x.data(), v.data(), w.data(), r.data()};
    json bs = backend_scene(scene);
    if (!contacts.is_null()) bs["contacts"] = contacts;
    CreateContext ctx{Params(params), bs, StateView(sv), Elements{}, "bench"};
    be = std::make_unique<SdfBackend>(ctx);
  }
  void step(double dt, double gx, double gy) {
    for (std::size_t i = 0; i < w.size(); ++i) {
      v[2 * i] += dt * gx;
      v[2 * i + 1] += dt * gy;
    }
    pinsim_state_mut sm{w.size(), t, x.data(), v.data(), w.data(), r.data()};
    MutableState ms(sm);
    pinsim_event_sink sink{this,
                           [](void* c, const pinsim_event*) { ++static_cast<World*>(c)->events; }};
    EventSink es(&sink);
    be->advance(ms, dt, es);
    t += dt;
  }
  uint64_t hash() const {  // FNV-1a over the positions' bytes
    uint64_t h = 1469598103934665603ull;
    for (double d : x) {
      unsigned char b[sizeof d];
      std::memcpy(b, &d, sizeof d);
      for (unsigned char c : b) h = (h ^ c) * 1099511628211ull;
    }
    return h;
  }
};

double median(std::vector<double> a) {
  std::sort(a.begin(), a.end());
  return a[a.size() / 2];
}

void row(const char* bench, const std::string& variant, std::size_t balls, int repeats, double med,
         const char* unit, uint64_t hash) {
  std::printf("%s,%s,%zu,%d,%.2f,%s,%016llx\n", bench, variant.c_str(), balls, repeats, med, unit,
              static_cast<unsigned long long>(hash));
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
  if (argc > 2 && std::string(argv[2]) == "--trace") {
    // the scene's ball: its contacts (time, obstacle id) and position every 0.25 s
    World w(scene, params_for(scene),
            {scene["particles"][0]["x"][0], scene["particles"][0]["x"][1]}, {0.0, 0.0}, radius);
    pinsim_event_sink sink{&w, [](void* c, const pinsim_event* e) {
                             const auto* wp = static_cast<World*>(c);
                             std::printf("event t=%.4f obstacle=%s vn %.3f -> %.3f\n", e->t,
                                         wp->be->field().obstacle(e->obstacle).id.c_str(),
                                         e->vn_before, e->vn_after);
                           }};
    const int steps = static_cast<int>(std::lround(duration / dt));
    for (int s = 0; s < steps; ++s) {
      for (std::size_t i = 0; i < w.w.size(); ++i) {
        w.v[2 * i] += dt * gx;
        w.v[2 * i + 1] += dt * gy;
      }
      pinsim_state_mut sm{w.w.size(), w.t, w.x.data(), w.v.data(), w.w.data(), w.r.data()};
      MutableState ms(sm);
      EventSink es(&sink);
      w.be->advance(ms, dt, es);
      w.t += dt;
      if (s % static_cast<int>(std::lround(0.25 / dt)) == 0)
        std::printf("t=%.2f x=(%.4f, %.4f) v=(%.3f, %.3f)\n", w.t, w.x[0], w.x[1], w.v[0], w.v[1]);
    }
    const auto& st = w.be->stats();
    std::printf("steps %llu skipped %llu queries %llu contacts %llu cap_hits %llu\n",
                (unsigned long long)st.particle_steps, (unsigned long long)st.skipped,
                (unsigned long long)st.queries, (unsigned long long)st.contacts,
                (unsigned long long)st.cap_hits);
    return 0;
  }
  std::printf("benchmark,variant,balls,repeats,median,unit,state_hash\n");

  // 1. distance queries at random points and times on the table
  for (const long cells : {16384L, 65536L, 262144L, 0L}) {
    World wq(scene, params_for(scene, {{"grid_cells", cells}}), {}, {}, radius);
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
        const auto t0 = Clock::now();
        for (std::size_t i = 0; i < n; ++i) sink += wq.be->distance(pts[i], ts[i], nullptr);
        runs.push_back(std::chrono::duration<double, std::nano>(Clock::now() - t0).count() / n);
      }
      uint64_t h = 0;
      std::memcpy(&h, &sink, sizeof h);
      row("sdf_query",
          (cells ? "grid_cells=" + std::to_string(cells) : std::string("brute_force")) +
              (coherent ? "_coherent_paths" : "_random_points"),
          0, 7, median(runs), "ns/query", h);
    }
  }

  // 2. ns per ball-step: the scene's own ball (plunger launch, flippers) for the full run,
  // and 100 / 10000 balls dropped at random into the playfield (no ball-ball contacts).
  struct Case {
    std::size_t balls;
    int steps;
    int repeats;
    bool pairs;
  };
  for (const Case c : {Case{1, 0, 5, false}, Case{100, 3000, 5, false}, Case{10000, 60, 5, false},
                       Case{100, 3000, 5, true}}) {
    std::vector<double> runs;
    uint64_t h = 0;
    double skipped = 0.0;
    for (int rep = 0; rep < c.repeats; ++rep) {
      std::vector<double> x0, v0;
      if (c.balls == 1) {
        x0 = {scene["particles"][0]["x"][0], scene["particles"][0]["x"][1]};
        v0 = {0.0, 0.0};
      } else {
        std::mt19937_64 rng(42);
        std::uniform_real_distribution<double> ux(0.05, 0.40), uy(0.35, 0.95), uv(-1.0, 1.0);
        for (std::size_t i = 0; i < c.balls; ++i) {
          Vec2 p;
          do p = Vec2(ux(rng), uy(rng));
          while (false);
          x0.push_back(p.x());
          x0.push_back(p.y());
          v0.push_back(uv(rng));
          v0.push_back(uv(rng));
        }
      }
      json contacts = c.pairs ? json{{"particles", true}, {"restitution", 0.9}} : json(nullptr);
      World wb(scene, params_for(scene), x0, v0, radius, contacts);
      // balls that start inside an obstacle are moved out of the way first (not timed)
      for (std::size_t i = 0; i < c.balls; ++i) {
        for (int k = 0; k < 100 && wb.be->distance(Vec2(wb.x[2 * i], wb.x[2 * i + 1]), 0.0,
                                                   nullptr) < radius + 1e-3;
             ++k)
          wb.x[2 * i + 1] += 0.01;
      }
      const int steps = c.steps ? c.steps : static_cast<int>(std::lround(duration / dt));
      const auto t0 = Clock::now();
      for (int s = 0; s < steps; ++s) wb.step(dt, gx, gy);
      const double ns = std::chrono::duration<double, std::nano>(Clock::now() - t0).count();
      runs.push_back(ns / (static_cast<double>(steps) * static_cast<double>(c.balls)));
      h = wb.hash();
      const auto& st = wb.be->stats();
      skipped = static_cast<double>(st.skipped) / static_cast<double>(st.particle_steps);
    }
    std::string variant = c.balls == 1 ? "scene_ball_full_run" : "random_drop";
    if (c.pairs) variant += "_ball_contacts";
    variant += "_skipped=" + std::to_string(skipped).substr(0, 5);
    row("ball_step", variant, c.balls, c.repeats, median(runs), "ns/ball-step", h);
  }
  return 0;
}
