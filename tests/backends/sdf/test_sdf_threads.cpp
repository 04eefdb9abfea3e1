// The sdf backend on threads with ball-ball contacts (docs/threads.md): the pair contacts'
// stages and the marches split their particles into fixed chunks and combine them in chunk
// order, and the hits are ordered by their (time, i, j) keys, never by the threads. A crowd
// falling on a floor and a bumper must give the same positions, velocities, events and
// counters to the bit with 1 (the serial loop), 2 and 3 threads.
#include <catch2/catch.hpp>
#include <cstring>
#include <vector>
#ifdef PINSIM_WITH_TBB
#include <tbb/global_control.h>
#endif

#include "sdf_harness.hpp"

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

/// 1500 balls of 1 cm, 2.1 cm apart, moving down and sideways at different speeds (every
/// 29th pinned), 80 steps of 1 ms under gravity onto a floor and a round bumper.
Run crowd_run(int threads) {
#ifdef PINSIM_WITH_TBB
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                  static_cast<std::size_t>(threads));
#else
  (void)threads;
#endif
  std::vector<Ball> balls;
  for (int k = 0; k < 1500; ++k) {
    Ball b;
    b.x = Vec2(-0.5 + 0.021 * (k % 50), 0.05 + 0.021 * (k / 50));
    b.v = Vec2(0.3 * ((k * 7) % 11 - 5), -0.5 - 0.1 * ((k * 3) % 7));
    b.r = 0.01;
    b.inv_mass = k % 29 == 0 ? 0.0 : 1.0 / (0.01 + 0.001 * (k % 5));
    balls.push_back(b);
  }
  const json scene = {
      {"obstacles",
       {obstacle("floor", {{"type", "box"}, {"center", {0.0, -0.5}}, {"half_size", {2.0, 0.5}}},
                 0.5, 0.1),
        obstacle("bumper", {{"type", "circle"}, {"center", {0.0, 0.1}}, {"radius", 0.1}}, 0.9)}},
      {"contacts", {{"particles", true}, {"restitution", 0.5}}}};
  Sim sim(scene, balls);
  for (int s = 0; s < 80; ++s) sim.step(1e-3, Vec2(0.0, -9.81));
  Run r{sim.x, sim.v, sim.events, sim.backend->stats()};
  for (const pinsim_event& e : sim.events) ++(e.obstacle < 0 ? r.pair_events : r.obstacle_events);
  return r;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

}  // namespace

TEST_CASE("sdf threads: a crowd with ball contacts gives the same bits on 1, 2 and 3 threads") {
  const Run one = crowd_run(1);
  // both kinds of events, many of them: every stage has work
  REQUIRE(one.pair_events > 1000);
  REQUIRE(one.obstacle_events > 100);
  for (int threads : {2, 3}) {
    const Run many = crowd_run(threads);
    CHECK(same_bits(one.x, many.x));
    CHECK(same_bits(one.v, many.v));
    REQUIRE(one.events.size() == many.events.size());
    for (std::size_t k = 0; k < one.events.size(); ++k)
      REQUIRE(std::memcmp(&one.events[k], &many.events[k], sizeof(pinsim_event)) == 0);
    CHECK(std::memcmp(&one.stats, &many.stats, sizeof(SdfStats)) == 0);
  }
}
