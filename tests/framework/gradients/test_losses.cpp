// Losses: their terms, gradients and the errors for bad specifications.
#include <catch2/catch.hpp>

#include "core/input_error.hpp"
#include "gradients/losses.hpp"

using namespace pinsim;
using namespace pinsim::grad;

namespace {
State two(double x0, double y0, double x1, double y1) {
  State s;
  s.x.resize(2, 2);
  s.x << x0, x1, y0, y1;
  s.v = Eigen::Matrix2Xd::Constant(2, 2, 0.5);
  s.inv_mass = Eigen::VectorXd::Ones(2);
  s.radius = Eigen::VectorXd::Constant(2, 0.01);
  return s;
}
}  // namespace

TEST_CASE("losses: final coordinate and target distance", "[gradients][losses]") {
  const LossContext ctx{100, 0.01, 2};
  Eigen::Matrix2Xd gx = Eigen::Matrix2Xd::Zero(2, 2), gv = gx;
  auto fin = parse_loss("final:1:y", ctx);
  CHECK(fin->has_term(100));
  CHECK_FALSE(fin->has_term(99));
  CHECK(fin->term(100, two(0, 0, 3, 4), gx, gv) == 4.0);
  CHECK(gx(1, 1) == 1.0);
  auto vel = parse_loss("final:0:vx", ctx);
  gx.setZero();
  CHECK(vel->term(100, two(0, 0, 3, 4), gx, gv) == 0.5);
  CHECK(gv(0, 0) == 1.0);
  auto tgt = parse_loss("target:1:1,2@0.5", ctx);
  CHECK(tgt->has_term(50));
  gx.setZero();
  // |(3, 4) - (1, 2)|^2 = 8, gradient 2 (2, 2)
  CHECK(tgt->term(50, two(0, 0, 3, 4), gx, gv) == 8.0);
  CHECK(gx(0, 1) == 4.0);
  CHECK(gx(1, 1) == 4.0);
  CHECK(parse_loss("target:0:1,2", ctx)->has_term(100));
}

TEST_CASE("losses: bad specifications name what was expected", "[gradients][losses]") {
  const LossContext ctx{100, 0.01, 2};
  CHECK_THROWS_WITH(parse_loss("final:5:y", ctx), Catch::Contains("particle 5 does not exist"));
  CHECK_THROWS_WITH(parse_loss("final:0:z", ctx), Catch::Contains("not x, y, vx or vy"));
  CHECK_THROWS_WITH(parse_loss("target:0:1,2@0.005", ctx), Catch::Contains("not a step time"));
  CHECK_THROWS_WITH(parse_loss("target:0:1@1", ctx), Catch::Contains("X,Y"));
  CHECK_THROWS_AS(parse_loss("nonsense", ctx), InputError);
  CHECK(step_of_time(0.3, 0.1) == 3);
  CHECK(step_of_time(0.35, 0.1) == -1);
}

TEST_CASE("losses: misfit to recorded frames", "[gradients][losses]") {
  const LossContext ctx{10, 0.1, 2};
  RecordedFrames f;
  f.source = "run";
  f.steps = {0, 10};
  f.x = {two(0, 0, 1, 1).x, two(1, 1, 2, 2).x};
  f.present = {{true, true}, {true, false}};
  auto m = make_misfit(f, ctx);
  Eigen::Matrix2Xd gx = Eigen::Matrix2Xd::Zero(2, 2), gv = gx;
  // frame at step 10: particle 0 only, |(2, 1) - (1, 1)|^2 = 1
  CHECK(m->term(10, two(2, 1, 9, 9), gx, gv) == 1.0);
  CHECK(gx(0, 0) == 2.0);
  CHECK(gx(0, 1) == 0.0);
  CHECK_FALSE(m->has_term(5));
  f.steps = {0, 11};
  CHECK_THROWS_WITH(make_misfit(f, ctx), Catch::Contains("past the run"));
}
