// The sdf backend on threads with ball-ball contacts (docs/threads.md): the pair contacts'
// stages and the marches split their particles into fixed chunks and combine them in chunk
// order, and the hits are ordered by their (time, i, j) keys, never by the threads. A crowd
// falling on a floor and a bumper, and a pile resting on the floor, must give the same
// positions, velocities, events and counters to the bit with 1 (the serial loop), 2 and 3
// threads.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <vector>
#ifdef PINSIM_WITH_TBB
#include <tbb/global_control.h>
#endif

#include "sdf_harness.hpp"
#include "test_support.hpp"

using namespace pinsim;
using namespace pinsim::sdf;
using namespace pinsim::sdf::test;
using nlohmann::json;

namespace {

struct Run {
  std::vector<double> x, v;
  std::vector<pinsim_event> events;
  SdfStats stats;
  std::size_t pair_events = 0, obstacle_events = 0;
};

/// A floor and a round bumper; ball contacts if `pairs`.
json table(bool pairs = true) {
  return {
      {"obstacles",
       {obstacle("floor", {{"type", "box"}, {"center", {0.0, -0.5}}, {"half_size", {2.0, 0.5}}},
                 0.5, 0.1),
        obstacle("bumper", {{"type", "circle"}, {"center", {0.0, 0.1}}, {"radius", 0.1}}, 0.9)}},
      {"contacts", {{"particles", pairs}, {"restitution", 0.5}}}};
}

Run result(const Sim& sim) {
  Run r{sim.x, sim.v, sim.events, sim.backend->stats()};
  for (const pinsim_event& e : sim.events) ++(e.obstacle < 0 ? r.pair_events : r.obstacle_events);
  return r;
}

/// `steps` steps of 1 ms of the balls under gravity above the table, on `threads` threads.
Run run(int threads, const std::vector<Ball>& balls, int steps) {
#ifdef PINSIM_WITH_TBB
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                  static_cast<std::size_t>(threads));
#else
  (void)threads;
#endif
  Sim sim(table(), balls);
  for (int s = 0; s < steps; ++s) sim.step(1e-3, Vec2(0.0, -9.81));
  return result(sim);
}

/// 1500 (or `count`) balls of 1 cm, 2.1 cm apart, in rows of 50, moving down and sideways at
/// different speeds (every 29th pinned), to fall onto the floor and the bumper.
std::vector<Ball> crowd(int count = 1500) {
  std::vector<Ball> balls;
  for (int k = 0; k < count; ++k) {
    Ball b;
    b.x = Vec2(-0.5 + 0.021 * (k % 50), 0.05 + 0.021 * (k / 50));
    b.v = Vec2(0.3 * ((k * 7) % 11 - 5), -0.5 - 0.1 * ((k * 3) % 7));
    b.r = 0.01;
    b.inv_mass = k % 29 == 0 ? 0.0 : 1.0 / (0.01 + 0.001 * (k % 5));
    balls.push_back(b);
  }
  return balls;
}

/// A pile at rest: 2400 balls of 5 mm in touching rows of 60 (hexagonal, each row on the
/// one below), the lowest on the floor beside the bumper, masses varied (every 31st
/// pinned). Under gravity nearly every contact is a hit that touches at the start.
std::vector<Ball> pile() {
  std::vector<Ball> balls;
  const double r = 0.005, rise = r * std::sqrt(3.0);
  for (int k = 0; k < 2400; ++k) {
    const int row = k / 60, col = k % 60;
    Ball b;
    b.x = Vec2(-0.9 + 2.0 * r * col + (row % 2) * r, r + rise * row);
    b.v = Vec2(0.0, 0.0);
    b.r = r;
    b.inv_mass = k % 31 == 0 ? 0.0 : 1.0 / (0.01 + 0.001 * (k % 7));
    balls.push_back(b);
  }
  return balls;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

void require_same(const Run& one, const Run& many) {
  CHECK(same_bits(one.x, many.x));
  CHECK(same_bits(one.v, many.v));
  REQUIRE(one.events.size() == many.events.size());
  for (std::size_t k = 0; k < one.events.size(); ++k)
    REQUIRE(std::memcmp(&one.events[k], &many.events[k], sizeof(pinsim_event)) == 0);
  CHECK(std::memcmp(&one.stats, &many.stats, sizeof(SdfStats)) == 0);
}

/// body(pairs) with ball contacts and without, each on 1 and 2 threads.
template <class Body>
void each_setting(Body&& body) {
  for (const bool pairs : {true, false})
    for (const int threads : {1, 2}) {
      CAPTURE(pairs, threads);
#ifdef PINSIM_WITH_TBB
      const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                      static_cast<std::size_t>(threads));
#endif
      body(pairs);
    }
}

}  // namespace

TEST_CASE("sdf threads: a crowd with ball contacts gives the same bits on 1, 2 and 3 threads") {
  const Run one = run(1, crowd(), 80);
  // both kinds of events, many of them: every stage has work
  REQUIRE(one.pair_events > 1000);
  REQUIRE(one.obstacle_events > 100);
  for (int threads : {2, 3}) require_same(one, run(threads, crowd(), 80));
}

TEST_CASE("sdf threads: a resting pile gives the same bits on 1, 2 and 3 threads") {
  // Each step's hits touch at the start, in order of (i, j): on threads the particles in
  // hits are marched while the resolution is still going, as soon as it is past them
  // (several times, as when they are marched depends on the threads' timing).
  const Run one = run(1, pile(), 40);
  REQUIRE(one.pair_events > 40 * 2000);  // about one hit per ball and step
  for (int threads : {2, 2, 2, 3}) require_same(one, run(threads, pile(), 40));
}

// A step in which a particle would travel beyond the backend's limit (1e9 per step) is
// refused before anything moves, naming the first such particle in index order (a NaN
// velocity counts; a pinned particle's velocity does not); with ball contacts the sweep of
// their first stage checks (1500 balls: one thread; on threads in chunks, the next test).
// The refused step changes nothing: with the velocities put back, the run goes on to the
// same bits as a run that never had it.
TEST_CASE("sdf threads: a step too fast is refused first, naming the first offender") {
  each_setting([](bool pairs) {
    const double dt = 1e-3;
    const Vec2 g(0.0, -9.81);
    Sim plain(table(pairs), crowd()), refused(table(pairs), crowd());
    for (int s = 0; s < 30; ++s) {
      plain.step(dt, g);
      refused.step(dt, g);
    }
    const std::vector<double> x = refused.x, v = refused.v;
    // ball 1160 is pinned (every 29th); 1100 and 1400 move (a travel of 2e9 > 1e9)
    REQUIRE(refused.w[1160] == 0.0);
    refused.v[2 * 1160] = std::nan("");
    refused.v[2 * 1400 + 1] = -2e12;
    refused.v[2 * 1100] = 2e12;
    std::vector<double> gone = refused.v;
    const pinsim::test::FpTrapsOff traps;  // (comparisons with the NaNs)
    REQUIRE_THROWS_WITH(refused.step(dt, Vec2::Zero()),
                        Catch::Contains("particle 1100 at t = ") &&
                            Catch::Contains("travels beyond the sdf backend's limit"));
    refused.v[2 * 1100] = std::nan("");
    gone[2 * 1100] = std::nan("");
    REQUIRE_THROWS_WITH(refused.step(dt, Vec2::Zero()), Catch::Contains("particle 1100 at t = "));
    refused.v[2 * 1100] = v[2 * 1100];
    gone[2 * 1100] = v[2 * 1100];
    REQUIRE_THROWS_WITH(refused.step(dt, Vec2::Zero()), Catch::Contains("particle 1400 at t = "));
    // nothing moved, no velocity changed, no event emitted
    CHECK(same_bits(refused.x, x));
    CHECK(std::memcmp(refused.v.data(), gone.data(), v.size() * sizeof(double)) == 0);
    CHECK(refused.events.size() == plain.events.size());
    refused.v = v;
    for (int s = 0; s < 30; ++s) {
      plain.step(dt, g);
      refused.step(dt, g);
    }
    require_same(result(plain), result(refused));
  });
}

// The same check on threads: from 4096 particles the sweep (with ball contacts) and the check
// without them run in chunks of 1024 on the threads, each chunk noting its first offender; the
// first chunk's is named, whichever thread ran it. Offenders in chunks 1 and 4 (finite
// velocities: the threads' floating-point traps stay on).
TEST_CASE("sdf threads: on threads the first offender is named across the chunks") {
  each_setting([](bool pairs) {
    Sim sim(table(pairs), crowd(6000));
    for (int s = 0; s < 5; ++s) sim.step(1e-3, Vec2(0.0, -9.81));
    REQUIRE(sim.w[4500] > 0.0);
    REQUIRE(sim.w[2000] > 0.0);
    const std::vector<double> x = sim.x;
    sim.v[2 * 4500] = 3e12;
    sim.v[2 * 2000 + 1] = -3e12;
    const std::vector<double> v = sim.v;
    REQUIRE_THROWS_WITH(sim.step(1e-3, Vec2::Zero()), Catch::Contains("particle 2000 at t = "));
    sim.v[2 * 2000 + 1] = 0.0;
    REQUIRE_THROWS_WITH(sim.step(1e-3, Vec2::Zero()), Catch::Contains("particle 4500 at t = "));
    CHECK(same_bits(sim.x, x));
  });
}
