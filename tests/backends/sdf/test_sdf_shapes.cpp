// SDF primitives: exact distances at known points, gradients against finite differences,
// finite unit gradients at singular points, and scene validation messages.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "sdf_harness.hpp"

using namespace pinsim;
using namespace pinsim::sdf;
using namespace pinsim::sdf::test;
using nlohmann::json;

namespace {

ShapeTree shape(const json& j) { return ShapeTree::parse(JsonIn(j, "shape", "test.json")); }

/// Central-difference gradient; the exact SDFs are smooth away from medial axes.
Vec2 fd_grad(const ShapeTree& s, const Vec2& p, double h = 1e-6) {
  return {(s.eval<false>(p + Vec2(h, 0)).d - s.eval<false>(p - Vec2(h, 0)).d) / (2 * h),
          (s.eval<false>(p + Vec2(0, h)).d - s.eval<false>(p - Vec2(0, h)).d) / (2 * h)};
}

const json kShapes[] = {
    {{"type", "circle"}, {"center", {0.1, -0.2}}, {"radius", 0.5}},
    {{"type", "box"}, {"center", {0.0, 0.1}}, {"half_size", {0.6, 0.3}}, {"angle", 0.4}},
    {{"type", "rounded_box"},
     {"center", {0.0, 0.0}},
     {"half_size", {0.5, 0.4}},
     {"corner_radius", 0.1}},
    {{"type", "capsule"}, {"a", {-0.5, 0.0}}, {"b", {0.4, 0.3}}, {"radius", 0.1}},
    {{"type", "tapered_capsule"},
     {"a", {0.0, 0.0}},
     {"b", {0.6, -0.2}},
     {"radius_a", 0.15},
     {"radius_b", 0.05}},
    {{"type", "polygon"}, {"points", {{0, 0}, {1, 0}, {1, 1}, {0.5, 0.3}, {0, 1}}}},
    {{"type", "arc"},
     {"center", {0, 0}},
     {"radius", 0.5},
     {"start_angle", 0.3},
     {"end_angle", 2.5},
     {"thickness", 0.06}},
    {{"type", "half_plane"}, {"point", {0, 0.2}}, {"normal", {1, 1}}},
    {{"type", "subtraction"},
     {"shapes",
      {{{"type", "box"}, {"center", {0, 0}}, {"half_size", {0.5, 0.5}}},
       {{"type", "circle"}, {"center", {0.5, 0.5}}, {"radius", 0.3}}}},
     {"transform", {{"translate", {0.2, 0.1}}, {"rotate", 0.7}}}},
    {{"type", "inside"}, {"shape", {{"type", "box"}, {"center", {0, 0}}, {"half_size", {1, 0.7}}}}},
};

}  // namespace

TEST_CASE("exact distances of the primitives at known points") {
  // circle: |p - c| - r
  CHECK(shape(kShapes[0]).eval<false>({0.1, 0.8}).d == Approx(0.5));
  // box rotated by 0.4: a point along its local +x axis at 1.0 from the centre -> 1.0 - 0.6
  const Vec2 ax(std::cos(0.4), std::sin(0.4));
  CHECK(shape(kShapes[1]).eval<false>(Vec2(0.0, 0.1) + 1.0 * ax).d == Approx(0.4));
  // box corner region: distance to the corner (0.6, 0.3) rotated
  const Vec2 corner = Vec2(0, 0.1) + Eigen::Rotation2Dd(0.4) * Vec2(0.6, 0.3);
  const Vec2 dir = (Eigen::Rotation2Dd(0.4) * Vec2(1, 1)).normalized();
  CHECK(shape(kShapes[1]).eval<false>(corner + 0.2 * dir).d == Approx(0.2));
  // rounded box: outer extents stay half_size; corner arc centre (0.4, 0.3), radius 0.1
  CHECK(shape(kShapes[2]).eval<false>({0.7, 0.0}).d == Approx(0.2));
  CHECK(shape(kShapes[2]).eval<false>({0.4 + 0.3 / std::sqrt(2.0), 0.3 + 0.3 / std::sqrt(2.0)}).d ==
        Approx(0.2));
  // capsule: beyond the end point b: |p - b| - r
  CHECK(shape(kShapes[3]).eval<false>({0.4, 0.8}).d == Approx(0.4));
  // polygon: the reflex vertex (0.5, 0.3) is a notch; (0.5, 0.5) is outside, 0.2 above it
  CHECK(shape(kShapes[5]).eval<false>({0.5, 0.5}).d == Approx(0.1 / std::sqrt(0.74)));
  CHECK(shape(kShapes[5]).eval<false>({0.9, 0.5}).d == Approx(-0.1));
  // arc: on the ring at angle 1.4 (inside the sweep), 0.2 outside the curve
  CHECK(shape(kShapes[6]).eval<false>(0.7 * Vec2(std::cos(1.4), std::sin(1.4))).d == Approx(0.17));
  // arc: beyond the end angle: distance to the rounded end
  const Vec2 end = 0.5 * Vec2(std::cos(2.5), std::sin(2.5));
  const Vec2 tang(std::sin(2.5), -std::cos(2.5));  // away from the sweep
  CHECK(shape(kShapes[6]).eval<false>(end - 0.3 * tang).d == Approx(0.27));
  // half-plane: (p - point) . n
  CHECK(shape(kShapes[7]).eval<false>({1, 1.2}).d == Approx(std::sqrt(2.0)));
  // container: inside the box the distance to the nearest wall, positive
  CHECK(shape(kShapes[9]).eval<false>({0.5, 0.0}).d == Approx(0.5));
  CHECK(shape(kShapes[9]).eval<false>({2.0, 0.0}).d == Approx(-1.0));
}

TEST_CASE("distances without and with the gradient are the same bits") {
  // Queries that need no gradient take branch-free paths (a circle and a capsule are
  // evaluated as rounded boxes, polygons and tapered capsules select without branching);
  // the distance must not depend on which path computed it.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (const json& j : kShapes) {
    const ShapeTree s = shape(j);
    for (int n = 0; n < 20000; ++n) {
      const Vec2 p(u(rng), u(rng));
      INFO(j.dump() << " at (" << p.x() << ", " << p.y() << ")");
      REQUIRE(s.eval<false>(p).d == s.eval<true>(p).d);
    }
  }
}

TEST_CASE("circle and capsule as rounded boxes agree with their direct formulas") {
  // circle: |p - c| - r, the same bits (rotation by the identity and a zero half size add
  // nothing); capsule: |p - a - h (b - a)| - r with h = clamp((p - a).(b - a) / |b - a|^2,
  // 0, 1), to rounding (the rounded-box form measures from the midpoint instead)
  const ShapeTree circle = shape(kShapes[0]), capsule = shape(kShapes[3]);
  const Vec2 c(0.1, -0.2), a(-0.5, 0.0), ab = Vec2(0.4, 0.3) - a;
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (int n = 0; n < 20000; ++n) {
    const Vec2 p(u(rng), u(rng));
    REQUIRE(circle.eval<false>(p).d == (p - c).norm() - 0.5);
    const double h = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    REQUIRE(capsule.eval<false>(p).d == Approx((p - a - h * ab).norm() - 0.1).margin(1e-15));
  }
}

TEST_CASE("gradients match finite differences and are unit length") {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (const json& j : kShapes) {
    const ShapeTree s = shape(j);
    int checked = 0;
    for (int k = 0; k < 400; ++k) {
      const Vec2 p(u(rng), u(rng));
      const Sdf e = s.eval<true>(p);
      REQUIRE(std::isfinite(e.d));
      CHECK(e.g.norm() == Approx(1.0).epsilon(1e-12));
      CHECK(s.eval<false>(p).d == e.d);
      const Vec2 fd = fd_grad(s, p);
      if (std::abs(fd.norm() - 1.0) > 1e-4) continue;  // on a medial axis: not differentiable
      CHECK((fd - e.g).norm() < 1e-5);
      ++checked;
    }
    CHECK(checked > 300);
  }
}

TEST_CASE("gradients at singular points are finite unit vectors") {
  const std::vector<std::pair<json, Vec2>> cases = {
      {kShapes[0], {0.1, -0.2}},  // circle centre
      {kShapes[1], {0.0, 0.1}},   // box centre
      {{{"type", "box"}, {"center", {0, 0}}, {"half_size", {0.5, 0.5}}}, {0.2, 0.2}},  // diagonal
      {{{"type", "rounded_box"},
        {"center", {0, 0}},
        {"half_size", {0.5, 0.5}},
        {"corner_radius", 0.5}},
       {0, 0}},  // rounded box that is a disc
      {{{"type", "capsule"}, {"a", {0, 0}}, {"b", {1, 0}}, {"radius", 0.0}},
       {0.5, 0.0}},  // on segment
      {{{"type", "capsule"}, {"a", {0, 0}}, {"b", {0, 0}}, {"radius", 0.0}}, {0.0, 0.0}},  // point
      {kShapes[4], {0.0, 0.0}},  // tapered capsule centre a
      {kShapes[5], {1.0, 0.0}},  // polygon vertex
      {kShapes[5], {0.5, 0.0}},  // polygon edge
      {kShapes[6], {0.0, 0.0}},  // arc centre
      {kShapes[9], {0.0, 0.0}},  // container centre
  };
  for (const auto& [j, p] : cases) {
    const Sdf e = shape(j).eval<true>(p);
    CHECK(std::isfinite(e.d));
    CHECK(std::isfinite(e.g.x()));
    CHECK(e.g.norm() == Approx(1.0));
  }
}

TEST_CASE("boolean operations and transforms") {
  const json a = {{"type", "circle"}, {"center", {0, 0}}, {"radius", 1.0}};
  const json b = {{"type", "circle"}, {"center", {1.5, 0}}, {"radius", 1.0}};
  const Vec2 p(0.75, 0.0);
  const double da = shape(a).eval<false>(p).d, db = shape(b).eval<false>(p).d;
  CHECK(shape({{"type", "union"}, {"shapes", {a, b}}}).eval<false>(p).d == std::min(da, db));
  CHECK(shape({{"type", "intersection"}, {"shapes", {a, b}}}).eval<false>(p).d == std::max(da, db));
  CHECK(shape({{"type", "subtraction"}, {"shapes", {a, b}}}).eval<false>(p).d == std::max(da, -db));
  // transform: a circle at the origin translated to (2, 1) and rotated (rotation is about
  // the local origin, so it does not move the centre)
  json c = {{"type", "circle"},
            {"center", {0, 0}},
            {"radius", 0.5},
            {"transform", {{"translate", {2, 1}}, {"rotate", 1.0}}}};
  CHECK(shape(c).eval<false>({2, 2}).d == Approx(0.5));
  // rotated box via transform equals the box's own angle
  json b1 = {{"type", "box"}, {"center", {0, 0}}, {"half_size", {0.6, 0.2}}, {"angle", 0.3}};
  json b2 = {{"type", "box"},
             {"center", {0, 0}},
             {"half_size", {0.6, 0.2}},
             {"transform", {{"rotate", 0.3}}}};
  for (const Vec2& q : {Vec2(0.7, 0.4), Vec2(-0.2, 0.1), Vec2(1.0, -1.0)})
    CHECK(shape(b1).eval<false>(q).d == Approx(shape(b2).eval<false>(q).d).margin(1e-14));
}

TEST_CASE("segment bounds hold at every point of the segment") {
  // ShapeTree::segment_bounds (used to take a sliding ball's step whole): for random
  // segments, short and long, every sampled point's SDF lies within the bounds; a triangle,
  // unions, intersections and containers of the primitives included.
  std::vector<json> shapes(std::begin(kShapes), std::end(kShapes));
  shapes.push_back({{"type", "polygon"}, {"points", {{0, 0}, {0.8, 0.1}, {0.2, 0.7}}}});
  shapes.push_back({{"type", "inside"},
                    {"shape",
                     {{"type", "union"},
                      {"shapes",
                       {{{"type", "box"}, {"center", {0, 0}}, {"half_size", {0.5, 0.4}}},
                        {{"type", "circle"}, {"center", {0, 0.4}}, {"radius", 0.5}}}}}}});
  shapes.push_back({{"type", "intersection"}, {"shapes", {kShapes[0], kShapes[3]}}});
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.2, 1.2), ul(-4.0, 0.5);
  for (const json& j : shapes) {
    const ShapeTree s = shape(j);
    for (int n = 0; n < 2000; ++n) {
      const Vec2 a(u(rng), u(rng));
      const double len = std::pow(10.0, ul(rng));
      const double ang = u(rng) * 3.0;
      const Vec2 b = a + len * Vec2(std::cos(ang), std::sin(ang));
      const auto [lo, hi] = s.segment_bounds(a, b);
      for (int k = 0; k <= 32; ++k) {
        const double f = s.eval<false>(a + (b - a) * (k / 32.0)).d;
        INFO(j.dump() << " segment " << n << " sample " << k);
        REQUIRE(f >= lo - 1e-12);
        REQUIRE(f <= hi + 1e-12);
      }
    }
  }
}

TEST_CASE("bad obstacles are rejected with the JSON path and what was expected") {
  auto err = [](const json& obstacles, const json& inputs = json::array()) {
    try {
      Sim sim({{"obstacles", obstacles}, {"inputs", inputs}}, {});
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const json circle = {{"type", "circle"}, {"center", {0, 0}}, {"radius", 1.0}};
  CHECK(err({{{"id", "a"}, {"shape", {{"type", "circle"}, {"center", {0, 0}}, {"radius", -1}}}}}) ==
        "test.json: obstacles[0].shape.radius: must be > 0, got -1");
  CHECK(err({{{"id", "a"}, {"shape", circle}, {"colour", "red"}}})
            .find("test.json: obstacles[0].colour: unknown key") == 0);
  CHECK(err({{{"id", "a"}, {"shape", circle}}, {{"id", "a"}, {"shape", circle}}}) ==
        "test.json: obstacles[1].id: duplicate obstacle id \"a\"");
  CHECK(err({{{"id", "a"}, {"shape", {{"type", "blob"}}}}})
            .find("test.json: obstacles[0].shape.type: unknown shape type 'blob'") == 0);
  CHECK(err({{{"id", "a"}, {"shape", circle}, {"material", {{"restitution", 1.5}}}}}) ==
        "test.json: obstacles[0].material.restitution: must be in [0, 1], got 1.5");
  CHECK(err({{{"id", "a"},
              {"shape",
               {{"type", "polygon"}, {"points", {{0, 0}, {2, 0}, {2, 2}, {1, -1}, {0, 2}}}}}}})
            .find("test.json: obstacles[0].shape.points: polygon is not simple") == 0);
  CHECK(
      err({{{"id", "a"},
            {"shape",
             {{"type", "union"}, {"shapes", {circle, {{"type", "box"}, {"center", {0, 0}}}}}}}}}) ==
      "test.json: obstacles[0].shape.shapes[1].half_size: required [x, y] is missing");
  CHECK(err({{{"id", "a"}, {"shape", circle}}},
            {{{"t", 1.0}, {"input", "left"}, {"action", "press"}}}) ==
        "test.json: inputs[0].input: no obstacle's motion listens to \"left\"");
  CHECK(err({{{"id", "a"},
              {"shape", circle},
              {"motion",
               {{"type", "flipper"},
                {"pivot", {0, 0}},
                {"rest_angle", 0},
                {"raised_angle", 1},
                {"angular_speed", 0},
                {"input", "l"}}}}}) ==
        "test.json: obstacles[0].motion.angular_speed: must be > 0, got 0");
}
