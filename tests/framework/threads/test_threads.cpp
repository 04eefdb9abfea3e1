// `pinsim run --threads N`: the state hash and the trajectory bytes do not depend on N.
//
// Why they must be equal (docs/threads.md): the host limits oneTBB to N threads; the only
// loops that use them split their work in chunks fixed by the item count
// (pinsim/parallel.hpp). The sdf backend marches each particle with its own inputs (pair
// contacts are resolved first, in waves of hits that share no particle, each particle's hits
// in their serial order) and adds counters and events per chunk, in chunk
// order; the SDK's ConstraintSpring computes each element's terms apart and subtracts them
// per particle in element order, the order of the serial loop. Implicit Euler's dot products
// are summed per fixed chunk of 1024 particle rows, then over the chunks in order: a
// grouping set by the particle count, not by N. So every double is computed by the same
// operations for any N.
#include <Eigen/Core>
#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <pinsim/parallel.hpp>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>
#ifdef PINSIM_WITH_TBB
#include <tbb/global_control.h>
#endif

#include "core/step_checks.hpp"
#include "test_support.hpp"

using nlohmann::json;

namespace {

const std::string configs = PINSIM_SOURCE_DIR "/configs";

/// 30 x 30 = 900 balls (above the sdf backend's parallel threshold of 256) falling onto a
/// floor and two round bumpers, with or without ball-ball contacts.
json many_balls(bool contacts) {
  json s = {{"name", "many_balls"},
            {"time", {{"dt", 0.001}, {"duration", 0.6}}},
            {"integrator", "symplectic_euler"},
            {"backend", {{"name", "sdf"}}},
            {"bodies",
             {{{"type", "grid_blob"},
               {"name", "balls"},
               {"origin", {-0.6, 0.2}},
               {"nx", 30},
               {"ny", 30},
               {"spacing", 0.04},
               {"mass", 0.01},
               {"radius", 0.012},
               {"velocity", {0.3, -1.0}}}}},
            {"forces", {{{"type", "gravity"}, {"params", {{"g", {0.0, -9.81}}}}}}},
            {"obstacles",
             {{{"id", "floor"},
               {"shape", {{"type", "box"}, {"center", {0.0, -0.5}}, {"half_size", {2.0, 0.5}}}},
               {"material", {{"restitution", 0.5}, {"friction", 0.1}}}},
              {{"id", "bumper"},
               {"shape", {{"type", "circle"}, {"center", {0.0, 0.1}}, {"radius", 0.15}}},
               {"material", {{"restitution", 0.9}}}}}},
            {"output", {{"every", 20}}}};
  if (contacts) s["contacts"] = {{"particles", true}, {"restitution", 0.5}};
  return s;
}

/// A 200 x 200 grid of damped springs dropping onto a floor: 79600 edges and 79202 shear
/// springs, each force above ConstraintSpring's parallel threshold (8192) and five chunks of
/// 16384 elements long, so some particles' terms are deferred (their elements span two
/// chunks); 40000 particles, 40 chunks of the per-particle loops (kParticleChunk 1024).
/// The rest lengths exceed the grid's spacings, so every spring pushes from the first step
/// and each particle's sum of terms depends on their order.
json spring_grid() {
  return {{"name", "spring_grid"},
          {"time", {{"dt", 0.0005}, {"duration", 0.03}}},
          {"integrator", "symplectic_euler"},
          {"backend", {{"name", "sdf"}}},
          {"bodies",
           {{{"type", "grid_blob"},
             {"name", "sheet"},
             {"origin", {-1.0, 0.05}},
             {"nx", 200},
             {"ny", 200},
             {"spacing", 0.01},
             {"mass", 0.001},
             {"radius", 0.003},
             {"velocity", {0.2, -2.0}}}}},
          {"forces",
           {{{"type", "gravity"}, {"params", {{"g", {0.0, -9.81}}}}},
            {{"type", "damped_spring"},
             {"params", {{"ks", 50.0}, {"kd", 0.01}, {"rest_length", 0.0105}}},
             {"elements", {{"body", "sheet"}, {"set", "edges"}}}},
            {{"type", "damped_spring"},
             {"params", {{"ks", 20.0}, {"kd", 0.01}, {"rest_length", 0.015}}},
             {"elements", {{"body", "sheet"}, {"set", "shear"}}}}}},
          {"obstacles",
           {{{"id", "floor"},
             {"shape", {{"type", "box"}, {"center", {0.0, -0.5}}, {"half_size", {2.0, 0.5}}}},
             {"material", {{"restitution", 0.3}}}}}},
          {"output", {{"every", 20}}}};
}

struct Run {
  json summary;
  std::string trajectory, events;
};

Run run(const std::string& scene, unsigned threads, const std::string& extra = "") {
  const auto dir = pinsim::test::temp_dir("threads");
  const auto r =
      pinsim::test::pinsim_cli("-q run " + scene + " --threads " + std::to_string(threads) + " " +
                               extra + " --out " + dir.string() + " --overwrite");
  INFO(r.output);
  REQUIRE(r.code == 0);
  Run out{json::parse(pinsim::test::read_file(dir / "summary.json")),
          pinsim::test::read_file(dir / "trajectory.csv"), ""};
  if (std::filesystem::exists(dir / "events.csv"))
    out.events = pinsim::test::read_file(dir / "events.csv");
  CHECK(out.summary["threads"] == threads);
  CHECK(out.summary["status"] == "ok");
  return out;
}

std::string write_scene(const json& s, const std::string& name) {
  const auto path = pinsim::test::temp_dir("threads-scene") / (name + ".json");
  std::ofstream(path) << s.dump(1);
  return path.string();
}

/// Runs the scene with 1, 2 and 3 threads and requires the same bits.
void same_for_1_2_3(const std::string& scene, const std::string& extra = "") {
  const Run one = run(scene, 1, extra);
  for (unsigned n : {2u, 3u}) {
    INFO(scene << " --threads " << n);
    const Run other = run(scene, n, extra);
    CHECK(other.summary["state_hash"] == one.summary["state_hash"]);
    CHECK(other.summary["contacts"] == one.summary["contacts"]);
    CHECK(other.trajectory == one.trajectory);
    CHECK(other.events == one.events);
  }
}

}  // namespace

TEST_CASE("threads: the pinball table gives the same bits with 1, 2 and 3 threads") {
  same_for_1_2_3(configs + "/pinball.json");
}

TEST_CASE("threads: 900 balls without ball contacts, 1, 2 and 3 threads alike") {
  const std::string scene = write_scene(many_balls(false), "balls");
  same_for_1_2_3(scene);
  // the scene does hit obstacles: the test is not about balls flying freely
  CHECK(run(scene, 2).summary["contacts"].get<uint64_t>() > 100);
}

TEST_CASE("threads: 900 balls with ball contacts, 1, 2 and 3 threads alike") {
  const std::string scene = write_scene(many_balls(true), "balls_contacts");
  same_for_1_2_3(scene);
}

TEST_CASE("threads: a grid of 158802 damped springs, 1, 2 and 3 threads alike") {
  const std::string scene = write_scene(spring_grid(), "springs");
  same_for_1_2_3(scene);
  // the sheet does reach the floor within the run
  CHECK(run(scene, 2).summary["contacts"].get<uint64_t>() > 0);
}

// Every integrator's per-particle updates (kick, accelerations, RK4's stage and final
// combinations, explicit Euler's kick after the drift) run in chunks; each must give the
// serial bits. Verlet's predictor kick runs too (damped springs are velocity dependent).
TEST_CASE("threads: the spring grid with every integrator, 1, 2 and 3 threads alike") {
  const std::string scene = write_scene(spring_grid(), "springs");
  for (const char* integrator : {"velocity_verlet", "rk4", "explicit_euler", "implicit_euler"}) {
    INFO(integrator);
    same_for_1_2_3(scene, std::string("--integrator ") + integrator + " --set time.duration=0.005");
  }
}

// XPBD projects each colour's constraints in chunks on threads: the colours share no moving
// particle, so the bits must not depend on the thread count (nor on the chunks).
TEST_CASE("threads: xpbd on the spring grid, 1, 2 and 3 threads alike") {
  const std::string scene = write_scene(spring_grid(), "springs");
  const std::string extra =
      "--integrator xpbd --set xpbd.substeps=3 --set xpbd.iterations=2 --set time.duration=0.005";
  same_for_1_2_3(scene, extra);
  const Run r = run(scene, 2, extra);
  CHECK(r.summary["solver"]["constraints"].get<uint64_t>() > 100000);
  CHECK(r.summary["solver"]["colours"].get<uint64_t>() >= 4);
}

// The same with the shear springs as pure dampers (ks = 0): xpbd solves them on the
// velocities, colour by colour in chunks, before the projection.
TEST_CASE("threads: xpbd's pure dampers on the spring grid, 1, 2 and 3 threads alike") {
  const std::string scene = write_scene(spring_grid(), "springs");
  const std::string extra =
      "--integrator xpbd --set xpbd.substeps=3 --set time.duration=0.005 "
      "--set forces[2].params.ks=0 --set forces[2].params.kd=0.5";
  same_for_1_2_3(scene, extra);
  const Run r = run(scene, 2, extra);
  CHECK(r.summary["solver"]["dampers"].get<uint64_t>() > 70000);
  CHECK(r.summary["solver"]["damper_colours"].get<uint64_t>() >= 2);
}

TEST_CASE("threads: the Box2D backend runs with threads (serially inside), same bits") {
  same_for_1_2_3(configs + "/pinball.json", "--backend box2d --set time.duration=1");
}

// run_both(first, second): first() on the calling thread (the sdf backend's resolving side
// emits the pair events from it into the caller's sink), second() beside it; with threads an
// exception from either reaches the caller only after both have ended, first()'s if both
// throw (without threads second() does not run after first() throws).
TEST_CASE("threads: run_both runs its first piece on the calling thread") {
#ifdef PINSIM_WITH_TBB
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
#endif
  const std::thread::id caller = std::this_thread::get_id();
  for (int k = 0; k < 50; ++k) {
    std::thread::id first_on;
    std::atomic<bool> second_ran{false};
    pinsim::run_both([&] { first_on = std::this_thread::get_id(); }, [&] { second_ran = true; });
    REQUIRE(first_on == caller);
    REQUIRE(second_ran.load());
  }
  // a second() that had started when first() threw has ended when the exception arrives
  // (one not yet started is cancelled: either is fine, a second() still running is not)
  std::atomic<int> started{0}, ended{0};
  auto slow = [&] {
    ++started;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    ++ended;
  };
  auto fail = [](const char* what) { return [what] { throw std::runtime_error(what); }; };
  auto wait_then_fail = [] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    throw std::runtime_error("first");
  };
  for (int k = 0; k < 10; ++k) {
    if (k % 2 == 0)
      CHECK_THROWS_WITH(pinsim::run_both(fail("first"), slow), "first");
    else
      CHECK_THROWS_WITH(pinsim::run_both(wait_then_fail, slow), "first");
    CHECK(started.load() == ended.load());
  }
  // (first() waiting 50 ms five times: a second() has started by then)
  if (pinsim::available_threads() > 1) CHECK(started.load() > 0);
  CHECK_THROWS_WITH(pinsim::run_both([] {}, fail("second")), "second");
  CHECK_THROWS_WITH(pinsim::run_both(fail("first"), fail("second")), "first");
}

TEST_CASE("threads: --threads outside 1..256 is refused with exit 2") {
  for (const char* bad : {"0", "257", "-1", "two"}) {
    INFO(bad);
    const auto r = pinsim::test::pinsim_cli("-q run " + configs + "/projectile.json --threads " +
                                            std::string(bad));
    CHECK(r.code == 2);
    CHECK_THAT(r.output, Catch::Matchers::Contains("--threads"));
  }
}

// StepChecks sums the kinetic energies K_i = m_i |v_i|^2 / 2 per fixed chunk of
// kParticleChunk particles and adds the chunk sums in chunk order (step_checks.cpp); the
// largest sum so far is the scale S_n of the growth bound, reported with a growth finding.
// The sum is computed here the same way and must match to the bit for 1, 2 and 3 threads;
// the data are chosen so that summing in another order (one serial sum) gives other bits.
TEST_CASE("threads: the step check's energy sums are combined in chunk order") {
  const Eigen::Index n = 80000;  // 79 chunks of 1024, on threads (above kParallelItems)
  pinsim::State s;
  s.x = Eigen::Matrix2Xd::Zero(2, n);
  s.v.resize(2, n);
  s.inv_mass.resize(n);
  s.radius = Eigen::VectorXd::Constant(n, 0.01);
  for (Eigen::Index i = 0; i < n; ++i) {
    // every third chunk sum small: adding the chunk sums in another order rounds differently
    const double scale[] = {1.0, 1e-3, 2.0};
    const double a = scale[(static_cast<std::size_t>(i) / pinsim::kParticleChunk) % 3];
    s.v(0, i) = a * std::sin(0.37 * static_cast<double>(i)) * (1.0 + static_cast<double>(i % 13));
    s.v(1, i) = a * std::cos(0.11 * static_cast<double>(i)) * 1e-3 * static_cast<double>(i % 101);
    s.inv_mass[i] = 1.0 / (1.0 + static_cast<double>(i % 7));
  }
  double chunked = 0.0, serial = 0.0;
  std::vector<double> parts;
  for (std::size_t c = 0; c < pinsim::chunk_count(n, pinsim::kParticleChunk); ++c) {
    double part = 0.0;
    const std::size_t end = std::min<std::size_t>(n, (c + 1) * pinsim::kParticleChunk);
    for (std::size_t i = c * pinsim::kParticleChunk; i < end; ++i) {
      const auto j = static_cast<Eigen::Index>(i);
      const double vx = s.v(0, j), vy = s.v(1, j);
      const double k = (0.5 / s.inv_mass[j]) * (vx * vx + vy * vy);
      part += k;
      serial += k;
    }
    chunked += part;
    parts.push_back(part);
  }
  REQUIRE(parts.size() >= 3);
  REQUIRE(static_cast<std::size_t>(n) >= pinsim::kParallelItems);
  // the order matters for these data: one serial sum, or the chunks added backwards, differ
  double backwards = 0.0;
  for (auto p = parts.rbegin(); p != parts.rend(); ++p) backwards += *p;
  REQUIRE(chunked != serial);
  REQUIRE(chunked != backwards);
  for (int threads : {1, 2, 3}) {
    INFO(threads << " threads");
#ifdef PINSIM_WITH_TBB
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(threads));
#endif
    pinsim::StepChecks checks;
    checks.start(s, 1e-300, 32.0);
    REQUIRE(!checks.check(s));  // the first step only records S = the sum
    pinsim::State burst = s;
    burst.v.col(7) *= 1e4;  // K_7 x 1e8: past G (K + S)
    const pinsim::StepFinding found = checks.check(burst);
    REQUIRE(found.what == pinsim::StepFinding::What::Growth);
    CHECK(found.particle == 7);
    CHECK(found.scale == chunked);
  }
}
