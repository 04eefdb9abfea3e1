// The pair scan's first test (pair_look.hpp) written on SSE2's pairs of doubles must give
// what the one on doubles one by one gives, to the bit, for every pair: the candidate bit
// (closed swept boxes that overlap, not both pinned), b = dx.dv and
// c = dx.dx - (r_P + r_Q)^2, from which look() decides whether the pair goes to the root.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "pair_look.hpp"
#include "test_support.hpp"

using pinsim::sdf::PairStart;

namespace {

/// Pairs of particles at many scales: random ones, exact touching and exact box contact,
/// equal coordinates, signed zeros, pinned ones, at rest.
std::vector<std::pair<PairStart, PairStart>> pairs_to_try(double dt) {
  std::vector<std::pair<PairStart, PairStart>> out;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const double scale : {1e-9, 1e-3, 1.0, 1e3, 1e8}) {
    for (int k = 0; k < 4000; ++k) {
      const double r1 = scale * (0.01 + 0.5 * std::abs(u(rng)));
      const double r2 = k % 3 == 0 ? r1 : scale * (0.01 + 0.5 * std::abs(u(rng)));
      PairStart p{
          scale * u(rng),         scale * u(rng), scale * u(rng) / dt, scale * u(rng) / dt, r1,
          k % 11 == 0 ? 0.0 : 1.0};
      PairStart q{p.x + 2.5 * scale * u(rng),
                  p.y + 2.5 * scale * u(rng),
                  scale * u(rng) / dt,
                  scale * u(rng) / dt,
                  r2,
                  k % 13 == 0 ? 0.0 : 2.0};
      if (k % 7 == 0) q.vx = q.vy = 0.0;
      if (k % 5 == 0) q.y = p.y;
      out.emplace_back(p, q);
      // touching and approaching head-on along x, and boxes that meet at one edge
      PairStart t = p;
      t.x = p.x + (p.r + q.r);
      t.vx = -p.vx;
      t.r = q.r;
      out.emplace_back(p, t);
      PairStart e = q;
      e.vx = e.vy = 0.0;
      PairStart f = p;
      f.vx = f.vy = 0.0;
      f.x = e.x + e.r + f.r;  // boxes share the edge x = e.x + e.r
      out.emplace_back(f, e);
    }
  }
  out.emplace_back(PairStart{0.0, -0.0, -0.0, 0.0, 1.0, 1.0},
                   PairStart{-0.0, 0.0, 0.0, -0.0, 1.0, 1.0});
  out.emplace_back(PairStart{-0.0, 0.0, 0.0, 0.0, 0.0, 1.0},
                   PairStart{0.0, 0.0, -0.0, 0.0, 0.0, 1.0});
  // a velocity of NaN or infinity (the swept box std::min and std::max make of it)
  const double nan = std::nan(""), inf = HUGE_VAL;
  for (const double bad : {nan, inf, -inf}) {
    out.emplace_back(PairStart{0.0, 0.0, bad, 0.0, 0.5, 1.0},
                     PairStart{0.9, 0.0, 0.0, 0.0, 0.5, 1.0});
    out.emplace_back(PairStart{0.0, 0.0, 0.0, 0.0, 0.5, 1.0},
                     PairStart{0.9, 0.2, 0.0, bad, 0.5, 1.0});
    out.emplace_back(PairStart{0.9, 0.2, 0.0, bad, 0.5, 1.0},
                     PairStart{0.0, 0.0, bad, 0.0, 0.5, 1.0});
  }
  return out;
}

}  // namespace

TEST_CASE("pair look: the packed figures equal the one by one figures to the bit") {
#if PINSIM_PAIR_LOOK_PACKED
  pinsim::test::FpTrapsOff traps;                     // (the NaN velocities)
  for (const double dt : {1e-4, 1.0 / 240.0, 0.5}) {  // (velocities scale with 1 / dt)
    std::size_t candidates = 0, left = 0, differ = 0;
    const auto pairs = pairs_to_try(dt);
    for (const auto& [p, q] : pairs) {
      const pinsim::sdf::PairFigures a = pinsim::sdf::figures_scalar(p, q, dt);
      const pinsim::sdf::PairFigures b = pinsim::sdf::figures_packed(p, q, dt);
      differ += static_cast<std::size_t>(a.candidate != b.candidate ||
                                         std::memcmp(&a.b, &b.b, sizeof a.b) != 0 ||
                                         std::memcmp(&a.c, &b.c, sizeof a.c) != 0);
      unsigned c = 0;
      candidates += a.candidate;
      left += pinsim::sdf::look(p, q, dt, c);
    }
    INFO("dt = " << dt << ": " << pairs.size() << " pairs, " << candidates << " candidates, "
                 << left << " left for the root");
    CHECK(differ == 0);
    // both outcomes of both bits occur
    CHECK(candidates > pairs.size() / 10);
    CHECK(candidates < pairs.size());
    CHECK(left > 100);
    CHECK(left < candidates);
  }
#else
  WARN("no SSE2 in this build: the packed test is not compiled");
#endif
}
