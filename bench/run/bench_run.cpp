// bench_run: end-to-end figures. For the same scenes, ns per particle-step of
//   - the sdf backend alone and Box2D 2.4.1 alone (ball scenes; linked directly, gravity and
//     symplectic Euler as the framework does them, thread CPU time, bench_world.hpp),
//   - `pinsim run` with the least output (first and last trajectory frames, no events: the
//     scene, plugins, integrator and checks), and
//   - `pinsim run --out DIR` with the scene's default output (trajectory.csv every
//     output.every steps, events.csv with output.events "impacts", contacts.csv) to a real
//     file,
// the last two from the CPU time of the run's step loop (summary.json's cpu_time_s: process
// CPU time, as the backend-only figures use CPU time on a possibly shared machine); also the
// loop's wall time (wall_time_s) and the max RSS of the run with output. Prints CSV, one
// row per case:
//   case,particles,steps,sdf_ns,box2d_ns,box2d_steps,run_min_output_ns,run_ns,
//   run_over_sdf,run_over_min_output,max_rss_mb,events_rows,contacts_rows,run_wall_s,
//   contacts,events_mb,contacts_mb
// (run_wall_s: the output run's loop wall time; contacts: impulses over the run, summary's
// contacts; events_mb, contacts_mb: the sizes of events.csv and contacts.csv.)
// Cases crowded_drop_10000_[anywhere_]events_*: issue 15's crowded drop, 10,000 balls
// dropped at random into the table (clear of the obstacles, or anywhere in the table's box),
// 0.2 s (1000 steps), a trajectory frame every 100 steps, with output.events impacts, all
// and none.
// The backend-alone figures run under a oneTBB limit of --threads N threads (1 if not given),
// as `pinsim run --threads N` does: sdf_ns is the process CPU time (every thread's) per
// ball-step, sdf_wall_ns the wall time; with N > 1 the same loop also runs with 1 thread and
// sdf_speedup = its wall time over the N-thread one (sdf_hash_same: 1 if both end in the same
// positions, to the bit). For cases with ball-ball contacts, sdf_no_pairs_ns is the same
// balls with contacts off (1 thread) and pairs_over_no_pairs = sdf_ns / sdf_no_pairs_ns at 1
// thread. Those loops (N threads, 1 thread, contacts off) run on copies of the case stepped
// in turn, 100 steps at a time (sdf_in_turn: on a shared host whose load changes over seconds
// the copies see the same load); with N > 1 each turn ends with N 1-thread copies at once,
// one per thread, and sdf_ceiling = N x the 1-thread wall time over theirs: what the machine
// itself gives this work on N threads, the ceiling of sdf_speedup (their positions must
// equal the 1-thread copy's too). With --repeat K they run K times: each figure is the median
// of its K, and the two ratios the medians of the K ratios of a round; each round's figures
// go to stderr.
// Usage: bench_run [--quick] [--threads N] [--repeat K] [--work DIR] [--pinsim PATH]
//                  [--only TEXT] [--backend-only]
//   --quick         small cases, a smoke test (ctest): checks it runs, no timing assertions
//   --threads       threads of the backend-alone loops and of `pinsim run --threads N` when
//                   pinsim has that flag (else a note)
//   --repeat        rounds of the backend-alone loops (default 1)
//   --work          folder for scenes and run output (default: a new folder under /tmp, removed)
//   --only          only the cases whose name contains TEXT
//   --backend-only  only the backend-alone figures (no `pinsim run`)
#include <malloc.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#ifdef PINSIM_WITH_TBB
#include <tbb/global_control.h>
#endif

#include "bench_world.hpp"
#include "box2d_backend.hpp"
#include "sdf_backend.hpp"

using namespace pinsim;
using namespace pinsim::bench;
using nlohmann::json;
using pinsim::box2d::Box2dBackend;
using pinsim::sdf::SdfBackend;
namespace fs = std::filesystem;

namespace {

struct Options {
  bool quick = false;
  int threads = 0;  ///< 0: not given
  int repeat = 1;   ///< rounds of the backend-alone loops
  std::string pinsim = PINSIM_EXE;
  fs::path work;
  bool threads_supported = false;
  bool backend_only = false;
};

/// One case: a scene file to run, and for ball scenes the backend-only worlds' inputs.
struct Case {
  std::string name;
  json scene;
  bool balls = false;   ///< particles are balls under gravity only: backend-only figures
  int box2d_steps = 0;  ///< Box2D runs this many of the steps (it is 10-40x slower)
  double radius = 0.0;  ///< balls
  double mass = 1.0;    ///< balls
  std::vector<double> x0, v0;
  json contacts;  ///< ball-ball contacts for the backend, or null
};

/// What a child run reports.
struct RunFigures {
  double loop_s = NAN;  ///< wall time of the step loop
  double max_rss_mb = NAN;
  double cpu_s = NAN;  ///< CPU time of the step loop (summary.json's cpu_time_s)
  double particles = 0.0;
  uint64_t events_rows = 0, contacts_rows = 0;
  uint64_t contacts = 0;  ///< impulses over the run (summary.json's contacts)
  double events_mb = 0.0, contacts_mb = 0.0;
  bool ok = false;
};

json read_json_file(const fs::path& p) {
  std::ifstream in(p);
  if (!in) throw std::runtime_error(p.string() + ": cannot open");
  std::stringstream ss;
  ss << in.rdbuf();
  return json::parse(ss.str(), nullptr, true, true);
}

// Runs pinsim with `args`, stdout+stderr into `log`; returns the exit status, the child's
// max RSS in `rss_mb`.
// (A forked child starts with this process's resident pages in its max RSS, which execv
// keeps: freed memory goes back to the system first, and cases are built only if selected.)
int spawn(const Options& o, const std::vector<std::string>& args, const fs::path& log,
          double& rss_mb, double* cpu_s = nullptr) {
  std::fflush(stdout);
  malloc_trim(0);
  const pid_t pid = fork();
  if (pid == 0) {
    std::FILE* f = std::freopen(log.c_str(), "w", stdout);
    if (f) dup2(fileno(stdout), 2);
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(o.pinsim.c_str()));
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(o.pinsim.c_str(), argv.data());
    _exit(127);
  }
  int status = 0;
  rusage ru{};
  if (pid < 0 || wait4(pid, &status, 0, &ru) < 0) return -1;
  rss_mb = static_cast<double>(ru.ru_maxrss) / 1024.0;
  if (cpu_s)
    *cpu_s = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
             1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

enum class Output { kDefault, kLeast };

// `pinsim run --out DIR` on the case's scene: with its default output, or with the least
// (the trajectory's first and last frames, no events: output.every = steps, output.events
// none).
RunFigures run_pinsim(const Options& o, const Case& c, int steps, Output mode) {
  const bool output = mode == Output::kDefault;
  const fs::path scene = o.work / (c.name + ".json");
  const fs::path out = o.work / (c.name + (output ? ".out" : ".min"));
  std::vector<std::string> args = {"-q",    "run",        scene.string(),
                                   "--out", out.string(), "--overwrite"};
  if (o.threads > 0 && o.threads_supported) {
    args.push_back("--threads");
    args.push_back(std::to_string(o.threads));
  }
  if (!output)
    args.insert(args.end(),
                {"--set", "output.every=" + std::to_string(steps), "--set", "output.events=none"});
  const fs::path log = o.work / (c.name + (output ? ".run.log" : ".min.log"));
  RunFigures f;
  const int rc = spawn(o, args, log, f.max_rss_mb);
  if (rc != 0) {
    std::fprintf(stderr, "bench_run: %s: pinsim exited %d (log %s):\n%s\n", c.name.c_str(), rc,
                 log.c_str(), slurp(log).c_str());
    return f;
  }
  const json s = read_json_file(out / "summary.json");
  f.loop_s = s.at("wall_time_s").get<double>();
  f.cpu_s = s.at("cpu_time_s").get<double>();
  f.particles = s.at("particles").get<double>();
  if (s.contains("events")) {
    f.events_rows = s["events"].value("events_rows", uint64_t{0});
    f.contacts_rows = s["events"].value("contacts_rows", uint64_t{0});
  }
  f.contacts = s.value("contacts", uint64_t{0});
  auto mb = [&](const char* name) {
    std::error_code ec;
    const auto n = fs::file_size(out / name, ec);
    return ec ? 0.0 : static_cast<double>(n) / 1e6;
  };
  f.events_mb = mb("events.csv");
  f.contacts_mb = mb("contacts.csv");
  f.ok = true;
  return f;
}

/// Backend-alone figures of one loop.
struct BackendFigures {
  double cpu_ns = NAN;   ///< process CPU time (all threads) per ball-step
  double wall_ns = NAN;  ///< wall time per ball-step
  uint64_t hash = 0;     ///< the positions at the end (BenchWorld::hash)
};

/// The figures of the rounds of one loop (at least one): their medians, the first round's
/// hash.
struct Rounds {
  std::vector<double> cpu, wall;
  uint64_t first_hash = 0;
  void add(const BackendFigures& f) {
    if (cpu.empty()) first_hash = f.hash;
    cpu.push_back(f.cpu_ns);
    wall.push_back(f.wall_ns);
  }
  BackendFigures medians() const { return {median(cpu), median(wall), first_hash}; }
};

double process_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return 1e9 * static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec);
}

/// Process CPU time and wall time, ns, summed over the blocks timed.
struct Timed {
  double cpu = 0.0, wall = 0.0;
  template <class F>
  void add(F&& f) {
    const auto w0 = std::chrono::steady_clock::now();
    const double t0 = process_cpu_ns();
    f();
    cpu += process_cpu_ns() - t0;
    wall += std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - w0).count();
  }
};

// Backend alone on `threads` threads (a oneTBB limit, as `pinsim run --threads`): per
// ball-step over the case's steps (Box2D: its first box2d_steps).
template <class B>
BackendFigures backend_ns(const Case& c, const json& params, const json& contacts, int steps,
                          double gx, double gy, int threads) {
#ifdef PINSIM_WITH_TBB
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                  static_cast<std::size_t>(std::max(threads, 1)));
#else
  (void)threads;
#endif
  BenchWorld<B> w(c.scene, params, c.x0, c.v0, c.radius, contacts, c.mass);
  const double dt = c.scene["time"]["dt"];
  Timed t;
  t.add([&] {
    for (int s = 0; s < steps; ++s) w.step(dt, gx, gy);
  });
  const double per = static_cast<double>(steps) * static_cast<double>(w.w.size());
  return {t.cpu / per, t.wall / per, w.hash()};
}

/// Steps of each copy per turn of sdf_in_turn.
constexpr int kTurnSteps = 100;

/// sdf_in_turn's figures: the N-thread copy, the 1-thread copy, the copy with contacts off;
/// the machine's ceiling (N 1-thread copies at once: N x one's wall time over theirs) and
/// whether those copies ended in one's positions.
struct InTurn {
  BackendFigures many, one, off;
  double ceiling = NAN;
  bool side_same = true;
};

// The sdf backend alone on copies of the case: `threads` threads, 1 thread, and (if the case
// has ball contacts) 1 thread with them off, stepped in turn kTurnSteps steps at a time, each
// copy's time summed over its turns. On a shared host whose load changes over seconds the
// copies see the same load, so their ratios hold where the figures of loops run one after
// another do not. (threads <= 1: one copy, as many and one.) With threads > 1 each turn
// ends with `threads` more 1-thread copies at once, one per thread (sharing nothing): the
// speedup the machine itself gives this work on that many threads, the ceiling of any
// splitting of it but where a thread's smaller share of the data helps the caches (on a
// shared host two cores may not run two threads at twice the speed of one).
InTurn sdf_in_turn(const Case& c, const json& params, int steps, double gx, double gy,
                   int threads) {
  using World = std::unique_ptr<BenchWorld<SdfBackend>>;
  auto world = [&](const json& contacts) {
    return std::make_unique<BenchWorld<SdfBackend>>(c.scene, params, c.x0, c.v0, c.radius, contacts,
                                                    c.mass);
  };
  struct Copy {
    World w;
    int threads = 1;
    Timed t;
  };
  std::vector<Copy> copies;
  copies.push_back({world(c.contacts), 1, {}});
  if (threads > 1) copies.push_back({world(c.contacts), threads, {}});
  if (!c.contacts.is_null()) copies.push_back({world({{"particles", false}}), 1, {}});
  std::vector<World> side;
  for (int k = 0; threads > 1 && k < threads; ++k) side.push_back(world(c.contacts));
  Timed side_t;
  const double dt = c.scene["time"]["dt"];
  for (int done = 0; done < steps; done += kTurnSteps) {
    const int end = std::min(steps, done + kTurnSteps);
    for (Copy& k : copies) {
#ifdef PINSIM_WITH_TBB
      const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                      static_cast<std::size_t>(k.threads));
#endif
      k.t.add([&] {
        for (int s = done; s < end; ++s) k.w->step(dt, gx, gy);
      });
    }
    if (side.empty()) continue;
#ifdef PINSIM_WITH_TBB
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
#endif
    std::vector<std::exception_ptr> failed(side.size());
    side_t.add([&] {
      std::vector<std::jthread> running;  // (joined also if a later one fails to start)
      for (std::size_t k = 0; k < side.size(); ++k)
        running.emplace_back([&, k] {
          try {
            for (int s = done; s < end; ++s) side[k]->step(dt, gx, gy);
          } catch (...) {
            failed[k] = std::current_exception();
          }
        });
      for (std::jthread& t : running) t.join();
    });
    for (const std::exception_ptr& e : failed)
      if (e) std::rethrow_exception(e);
  }
  auto figures = [&](const Copy& k) -> BackendFigures {
    const double per = static_cast<double>(steps) * static_cast<double>(k.w->w.size());
    return {k.t.cpu / per, k.t.wall / per, k.w->hash()};
  };
  InTurn out;
  out.one = figures(copies[0]);
  out.many = threads > 1 ? figures(copies[1]) : out.one;
  if (!c.contacts.is_null()) out.off = figures(copies.back());
  if (!side.empty()) {
    out.ceiling = static_cast<double>(side.size()) * copies[0].t.wall / side_t.wall;
    for (const auto& w : side) out.side_same = out.side_same && w->hash() == out.one.hash;
  }
  return out;
}

json particles_json(const std::vector<double>& x0, const std::vector<double>& v0, double radius,
                    double mass) {
  json p = json::array();
  for (std::size_t i = 0; i < x0.size() / 2; ++i)
    p.push_back({{"x", {x0[2 * i], x0[2 * i + 1]}},
                 {"v", {v0[2 * i], v0[2 * i + 1]}},
                 {"mass", mass},
                 {"radius", radius}});
  return p;
}

// Balls dropped at random into the playfield, clear of the obstacles (as bench_sdf).
void drop_balls(const SdfBackend& probe, double radius, std::size_t balls, std::vector<double>& x0,
                std::vector<double>& v0) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> ux(0.05, 0.40), uy(0.35, 0.95), uv(-1.0, 1.0);
  for (std::size_t i = 0; i < balls; ++i) {
    double px = 0.0, py = 0.0;
    do {
      px = ux(rng);
      py = uy(rng);
    } while (probe.distance(Vec2(px, py), 0.0, nullptr) < radius + 1e-3);
    x0.insert(x0.end(), {px, py});
    v0.insert(v0.end(), {uv(rng), uv(rng)});
  }
}

// Balls anywhere in the table's box [0, 0.5] x [0, 1], obstacles or not (a ball placed in
// an obstacle stays in contact with it): issue 15's crowded drop as it most likely was made.
void scatter_balls(std::size_t balls, std::vector<double>& x0, std::vector<double>& v0) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> ux(0.0, 0.5), uy(0.0, 1.0), uv(-1.0, 1.0);
  for (std::size_t i = 0; i < balls; ++i) {
    const double px = ux(rng), py = uy(rng);
    x0.insert(x0.end(), {px, py});
    v0.insert(v0.end(), {uv(rng), uv(rng)});
  }
}

// Balls on a lattice `spacing` apart (no two overlapping), clear of the obstacles, slow.
void lattice_balls(const SdfBackend& probe, double radius, double spacing, std::size_t balls,
                   std::vector<double>& x0, std::vector<double>& v0) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> uv(-0.1, 0.1);
  for (double py = 0.95; py > 0.05 && x0.size() / 2 < balls; py -= spacing)
    for (double px = 0.05; px < 0.40 && x0.size() / 2 < balls; px += spacing)
      if (probe.distance(Vec2(px, py), 0.0, nullptr) > radius + 1e-3) {
        x0.insert(x0.end(), {px, py});
        v0.insert(v0.end(), {uv(rng), uv(rng)});
      }
}

// A grid_blob cloth nx x ny hanging from its top row over the pinball table's backend-free
// space, damped springs on its edges and shear springs, gravity.
// Particles of 0.01 kg and springs soft enough (h w ~ 0.01 .. 0.03 at dt 1e-4, damping ratio
// ~0.05) that explicit Euler too stays stable over the run.
json cloth_scene(int nx, int ny, double spacing, int steps, const std::string& integrator,
                 int every) {
  const double total_mass = 0.01 * nx * ny;
  json pin = json::array();
  for (int i = 0; i < nx; ++i) pin.push_back((ny - 1) * nx + i);
  return {{"name", "cloth"},
          {"time", {{"dt", 1e-4}, {"duration", 1e-4 * steps}}},
          {"integrator", integrator},
          {"backend", {{"name", "none"}}},
          {"bodies",
           {{{"type", "grid_blob"},
             {"name", "cloth"},
             {"origin", {0.0, 0.0}},
             {"nx", nx},
             {"ny", ny},
             {"spacing", spacing},
             {"total_mass", total_mass},
             {"radius", spacing / 4},
             {"pin", pin}}}},
          {"forces",
           {{{"type", "gravity"}, {"params", {{"g", {0.0, -9.81}}}}},
            {{"type", "damped_spring"},
             {"params", {{"ks", 100.0}, {"kd", 0.1}}},
             {"elements", {{"body", "cloth"}, {"set", "edges"}}}},
            {{"type", "damped_spring"},
             {"params", {{"ks", 50.0}, {"kd", 0.05}}},
             {"elements", {{"body", "cloth"}, {"set", "shear"}}}}}},
          {"output", {{"every", every}}}};
}

Case scene_case(const std::string& name, json scene) {
  Case c;
  c.name = name;
  c.scene = std::move(scene);
  return c;
}

std::vector<Case> make_cases(const Options& o, const json& pinball, const std::string& only) {
  std::vector<Case> cases;
  const double r = pinball["particles"][0]["radius"];
  BenchWorld<SdfBackend> probe(pinball, params_for<SdfBackend>(pinball["backend"]["params"]), {},
                               {}, r);
  // pairs: balls of radius `pair_r` on a lattice `spacing` apart with ball-ball contacts
  // (restitution 0.5)
  auto ball_case = [&](const std::string& name, std::size_t n, int steps, bool pairs,
                       bool anywhere = false, double pair_r = 0.002, double spacing = 0.0045) {
    if (name.find(only) == std::string::npos) return;  // not selected: not built
    Case c;
    c.name = name;
    c.scene = pinball;
    c.balls = true;
    c.radius = r;
    c.mass = 1.0;
    if (pairs) {
      c.radius = pair_r;
      lattice_balls(*probe.be, c.radius, spacing, n, c.x0, c.v0);
      c.contacts = {{"particles", true}, {"restitution", 0.5}};
      c.scene["contacts"] = c.contacts;
    } else if (anywhere) {
      scatter_balls(n, c.x0, c.v0);
    } else {
      drop_balls(*probe.be, r, n, c.x0, c.v0);
    }
    c.scene["particles"] = particles_json(c.x0, c.v0, c.radius, c.mass);
    c.scene["time"]["duration"] = steps * c.scene["time"]["dt"].get<double>();
    c.box2d_steps = std::min(steps, static_cast<int>(std::max<std::size_t>(2000000 / n, 20)));
    cases.push_back(std::move(c));
  };
  // The scene's own ball, whole run.
  Case own;
  own.name = "scene_ball";
  own.scene = pinball;
  own.balls = true;
  own.radius = r;
  own.mass = pinball["particles"][0].value("mass", 1.0);
  own.x0 = {pinball["particles"][0]["x"][0], pinball["particles"][0]["x"][1]};
  own.v0 = {0.0, 0.0};
  const double dt = pinball["time"]["dt"];
  const int own_steps =
      o.quick ? 500 : static_cast<int>(std::lround(pinball["time"]["duration"].get<double>() / dt));
  own.scene["time"]["duration"] = own_steps * dt;
  own.box2d_steps = own_steps;
  cases.push_back(own);
  if (o.quick) {
    ball_case("drop_100", 100, 200, false);
    ball_case("drop_100_ball_contacts", 100, 200, true);
    cases.push_back(scene_case("cloth_10x10_symplectic_euler",
                               cloth_scene(10, 10, 0.02, 200, "symplectic_euler", 20)));
    cases.push_back(
        scene_case("springs_10k", cloth_scene(100, 50, 0.01, 20, "symplectic_euler", 10)));
    return cases;
  }
  // 3 s simulated (g = 1.11 m/s^2 along the table): the balls have fallen and lie in piles.
  ball_case("drop_100_settled", 100, 15000, false);
  ball_case("drop_10000_settled", 10000, 15000, false);
  ball_case("drop_10000_ball_contacts", 10000, 5000, true);
  // Multiball: 100,000 balls of 0.6 mm with ball-ball contacts, 0.2 s.
  ball_case("multiball_100000_ball_contacts", 100000, 1000, true, false, 0.0006, 0.00135);
  // Issue 15's crowded drop: 10,000 balls dropped at random, 0.2 s, a frame every 100 steps.
  // Dropped clear of the obstacles (drop_balls), and anywhere in the table's box.
  for (const char* where : {"", "anywhere_"})
    for (const char* mode : {"impacts", "all", "none"}) {
      const std::string name = std::string("crowded_drop_10000_") + where + "events_" + mode;
      ball_case(name, 10000, 1000, false, *where != '\0');
      if (cases.empty() || cases.back().name != name) continue;
      cases.back().scene["output"]["every"] = 100;
      cases.back().scene["output"]["events"] = mode;
    }
  for (const char* integ :
       {"explicit_euler", "symplectic_euler", "velocity_verlet", "rk4", "implicit_euler"})
    cases.push_back(scene_case(std::string("cloth_100x100_") + integ,
                               cloth_scene(100, 100, 0.01, 2000, integ, 100)));
  // 501 x 1000 grid: 1,000,499 edge springs (the shear springs dropped).
  Case springs =
      scene_case("springs_1M", cloth_scene(501, 1000, 0.002, 300, "symplectic_euler", 100));
  springs.scene["forces"].erase(2);  // edges only
  cases.push_back(springs);
  return cases;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  bool keep = false;
  std::string only;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") {
      o.quick = true;
    } else if (a == "--threads" && i + 1 < argc) {
      o.threads = std::atoi(argv[++i]);
    } else if (a == "--repeat" && i + 1 < argc) {
      o.repeat = std::atoi(argv[++i]);
      if (o.repeat < 1) {
        std::fprintf(stderr, "bench_run: --repeat: expected a whole number of rounds >= 1\n");
        return 2;
      }
    } else if (a == "--work" && i + 1 < argc) {
      o.work = argv[++i];
      keep = true;
    } else if (a == "--pinsim" && i + 1 < argc) {
      o.pinsim = argv[++i];
    } else if (a == "--backend-only") {
      o.backend_only = true;
    } else if (a == "--only" && i + 1 < argc) {
      only = argv[++i];
    } else {
      std::fprintf(stderr,
                   "usage: bench_run [--quick] [--threads N] [--repeat K] [--work DIR] [--pinsim "
                   "PATH] [--only TEXT] [--backend-only]\n");
      return 2;
    }
  }
  if (o.work.empty()) {
    char tmpl[] = "/tmp/bench_run.XXXXXX";
    if (!mkdtemp(tmpl)) {
      std::perror("bench_run: mkdtemp");
      return 1;
    }
    o.work = tmpl;
  }
  fs::create_directories(o.work);
  // the multiball scene lists 100,000 particles: above the scene reader's default limit of
  // 1,000,000 JSON values (kept if the caller set one)
  setenv("PINSIM_JSON_MAX_VALUES", "20000000", 0);
  {
    double rss = 0.0;
    spawn(o, {"run", "--help"}, o.work / "help.log", rss);
    o.threads_supported = slurp(o.work / "help.log").find("--threads") != std::string::npos;
  }
  if (o.threads > 0 && !o.threads_supported)
    std::fprintf(stderr, "bench_run: note: `pinsim run` has no --threads yet; ignored\n");

  const json pinball = read_json_file(fs::path(PINSIM_CONFIG_DIR) / "pinball.json");
  std::vector<Case> cases = make_cases(o, pinball, only);
  std::erase_if(cases, [&](const Case& c) { return c.name.find(only) == std::string::npos; });
  const double gx = pinball["forces"][0]["params"]["g"][0],
               gy = pinball["forces"][0]["params"]["g"][1];
  json box2d_params = pinball["crosscheck"]["params"]["box2d"];

  const int threads = std::max(o.threads, 1);
  std::printf(
      "case,particles,steps,sdf_ns,box2d_ns,box2d_steps,run_min_output_ns,run_ns,run_over_sdf,"
      "run_over_min_output,run_wall_ns,max_rss_mb,events_rows,contacts_rows,run_wall_s,contacts,"
      "events_mb,contacts_mb,threads,sdf_wall_ns,sdf_1t_wall_ns,sdf_speedup,sdf_hash_same,"
      "sdf_no_pairs_ns,pairs_over_no_pairs,sdf_ceiling\n");
  int failures = 0;
  for (const Case& c : cases) {
    {
      std::ofstream f(o.work / (c.name + ".json"));
      f << c.scene.dump(1) << "\n";
    }
    const double dt = c.scene["time"]["dt"];
    const int steps = static_cast<int>(std::lround(c.scene["time"]["duration"].get<double>() / dt));
    BackendFigures sdf, sdf1, no_pairs;
    double speedup = NAN, over_no_pairs = NAN, ceiling = NAN;
    bool same_hash = true;
    double box2d = NAN;
    if (c.balls) {
      const json sp = params_for<SdfBackend>(c.scene["backend"]["params"]);
      // o.repeat rounds in turn; the medians (Rounds)
      Rounds n, one, off;
      std::vector<double> speedups, overs, ceilings;
      for (int r = 0; r < o.repeat; ++r) {
        const InTurn f = sdf_in_turn(c, sp, steps, gx, gy, threads);
        const BackendFigures &a = f.many, &b = f.one;
        n.add(a);
        one.add(b);
        speedups.push_back(b.wall_ns / a.wall_ns);
        same_hash = same_hash && a.hash == n.first_hash && b.hash == n.first_hash && f.side_same;
        ceilings.push_back(f.ceiling);
        if (!c.contacts.is_null()) {
          off.add(f.off);
          overs.push_back(b.cpu_ns / f.off.cpu_ns);
        }
        if (o.repeat > 1)
          std::fprintf(stderr,
                       "bench_run: %s round %d: %d threads %.2f ns, 1 thread %.2f ns (%.2fx; "
                       "the machine's ceiling %.2fx), contacts off %.2f ns\n",
                       c.name.c_str(), r + 1, threads, a.wall_ns, b.wall_ns, b.wall_ns / a.wall_ns,
                       f.ceiling, f.off.cpu_ns);
      }
      sdf = n.medians();
      sdf1 = one.medians();
      speedup = median(speedups);
      if (threads > 1) ceiling = median(ceilings);
      if (!overs.empty()) {
        no_pairs = off.medians();
        over_no_pairs = median(overs);
      }
      try {
        box2d = backend_ns<Box2dBackend>(c, params_for<Box2dBackend>(box2d_params), c.contacts,
                                         c.box2d_steps, gx, gy, 1)
                    .cpu_ns;
      } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_run: %s: box2d failed: %s\n", c.name.c_str(), e.what());
      }
    }
    RunFigures bare, out;
    if (!o.backend_only) {
      bare = run_pinsim(o, c, steps, Output::kLeast);
      out = run_pinsim(o, c, steps, Output::kDefault);
      failures += !bare.ok + !out.ok;
    }
    // Particles from the run's own summary (bodies generate theirs).
    const double particles = out.ok ? out.particles : static_cast<double>(c.x0.size() / 2);
    const double per = 1e9 / (static_cast<double>(steps) * particles);
    // CPU time, as the backend-only figures (the machine may be shared).
    const double run_ns = out.cpu_s * per, bare_ns = bare.cpu_s * per, wall_ns = out.loop_s * per;
    std::printf(
        "%s,%.0f,%d,%.2f,%.2f,%d,%.2f,%.2f,%.2f,%.2f,%.2f,%.1f,%llu,%llu,%.2f,%llu,%.1f,%.1f,%d,"
        "%.2f,%.2f,%.2f,%d,%.2f,%.2f,%.2f\n",
        c.name.c_str(), particles, steps, sdf.cpu_ns, box2d, c.balls ? c.box2d_steps : 0, bare_ns,
        run_ns, run_ns / sdf.cpu_ns, run_ns / bare_ns, wall_ns, out.max_rss_mb,
        static_cast<unsigned long long>(out.events_rows),
        static_cast<unsigned long long>(out.contacts_rows), out.loop_s,
        static_cast<unsigned long long>(out.contacts), out.events_mb, out.contacts_mb, threads,
        sdf.wall_ns, sdf1.wall_ns, speedup, same_hash ? 1 : 0, no_pairs.cpu_ns, over_no_pairs,
        ceiling);
    std::fflush(stdout);
    // Sane figures: every measured one finite and positive (no timing limits); the same
    // positions for any thread count.
    std::vector<double> figures = {c.balls ? sdf.cpu_ns : 1.0};
    if (!o.backend_only) figures.insert(figures.end(), {run_ns, bare_ns, wall_ns, out.max_rss_mb});
    for (double v : figures)
      if (!(std::isfinite(v) && v > 0.0)) {
        std::fprintf(stderr, "bench_run: %s: a figure is not a positive number\n", c.name.c_str());
        ++failures;
        break;
      }
    if (c.balls && !same_hash) {
      std::fprintf(stderr,
                   "bench_run: %s: 1 and %d threads (or two rounds) end in different positions\n",
                   c.name.c_str(), threads);
      ++failures;
    }
    if (!keep) {
      fs::remove_all(o.work / (c.name + ".out"));
      fs::remove_all(o.work / (c.name + ".min"));
    }
  }
  if (!keep) fs::remove_all(o.work);
  return failures ? 1 : 0;
}
