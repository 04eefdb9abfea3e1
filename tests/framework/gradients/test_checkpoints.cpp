// The checkpointed passes: the same adjoint as keeping every step, about 2 sqrt(N) states.
#include <catch2/catch.hpp>
#include <cmath>
#include <vector>

#include "gradients/checkpoints.hpp"

using namespace pinsim::grad;

TEST_CASE("checkpoints: uniform plan sizes", "[gradients][checkpoints]") {
  CHECK(CheckpointPlan::uniform(1000).segment == 32);
  CHECK(CheckpointPlan::uniform(1000000).segment == 1000);
  CHECK(CheckpointPlan::uniform(1000000).peak_records() == 2000);
  CHECK(CheckpointPlan::uniform(1).segment == 1);
  CHECK(CheckpointPlan::uniform(0).segments() == 0);
  const auto p = CheckpointPlan::uniform(10, 4);
  CHECK(p.segments() == 3);
  CHECK(p.begin(2) == 8);
  CHECK(p.end(2) == 10);
}

// x_{n+1} = a_n x_n with a_n = 1 + 0.001 n (a step that depends on where it is): the
// adjoint of x_N with respect to x_0 is the product of the a_n, and every step is replayed
// exactly once from its checkpoint.
TEST_CASE("checkpoints: the backward pass replays each step once, in order",
          "[gradients][checkpoints]") {
  for (uint64_t steps : {1ull, 7ull, 64ull, 1000ull}) {
    const CheckpointPlan plan = CheckpointPlan::uniform(steps);
    struct Ck {
      uint64_t n;
      double x;
    };
    struct Tape {
      uint64_t n = 0;
      double x = 0.0;
    };
    uint64_t n = 0;
    double x = 1.0;
    uint64_t forward_steps = 0, replayed_steps = 0;
    auto save = [&] { return Ck{n, x}; };
    auto step = [&](Tape* t) {
      if (t) {
        t->n = n;
        t->x = x;
        ++replayed_steps;
      } else {
        ++forward_steps;
      }
      x *= 1.0 + 0.001 * static_cast<double>(n);
      ++n;
    };
    std::vector<uint64_t> seen;
    auto cks = forward_pass<Ck, Tape>(plan, save, step, [&](uint64_t k) { seen.push_back(k); });
    REQUIRE(seen.size() == steps);
    CHECK(cks.size() == plan.segments());
    double adj = 1.0;  // d x_N / d x_n
    uint64_t expect = steps;
    bool ordered = true;
    backward_pass<Ck, Tape>(
        plan, cks, [&](const Ck& c) { n = c.n, x = c.x; }, step,
        [&](uint64_t k, const Tape& t) {
          ordered = ordered && k == expect && t.n + 1 == k;
          --expect;
          adj *= 1.0 + 0.001 * static_cast<double>(t.n);
        },
        [&](uint64_t) {});
    CHECK(ordered);
    CHECK(expect == 0);
    CHECK(forward_steps == steps);
    CHECK(replayed_steps == steps);
    double prod = 1.0;
    for (uint64_t k = 0; k < steps; ++k) prod *= 1.0 + 0.001 * static_cast<double>(k);
    CHECK(adj == Approx(prod).epsilon(1e-12));
  }
}
