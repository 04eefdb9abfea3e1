// The box2d backend against closed forms and against the sdf reference, through the
// framework (pinsim::Simulation loading the plugins), and its errors.
#include <catch2/catch.hpp>
#include <cmath>
#include <pinsim/scene_field/obstacle_field.hpp>
#include <string>

#include "core/simulation.hpp"
#include "shape_builder.hpp"
#include "tools/crosscheck.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;

namespace {

const std::string kDir = PINSIM_CONFIG_DIR "/crosscheck/";

/// Runs `file` on both backends and compares them with the scene's tolerances.
CrosscheckReport crosscheck_file(const std::string& file,
                                 const std::vector<std::string>& set = {}) {
  const Scene scene = load_scene(file, set);
  const CrosscheckSpec spec = parse_crosscheck(scene);
  PluginLoader loader(plugin_search_dirs());
  const CrosscheckRun a = run_for_crosscheck(scene, loader, "sdf", spec);
  const CrosscheckRun b = run_for_crosscheck(scene, loader, "box2d", spec);
  REQUIRE(a.error.empty());
  REQUIRE(b.error.empty());
  return compare_runs(scene, spec, a, b);
}

/// The box2d run's contacts of a crosscheck scene.
std::vector<pinsim_event> box2d_events(const std::string& file) {
  const Scene scene = load_scene(file);
  PluginLoader loader(plugin_search_dirs());
  const CrosscheckRun r = run_for_crosscheck(scene, loader, "box2d", parse_crosscheck(scene));
  REQUIRE(r.error.empty());
  return r.events;
}

/// A one-ball scene without forces around `obstacles` (JSON text).
std::string scene_text(const std::string& obstacles, const std::string& ball,
                       const std::string& params = "{}", double dt = 0.001, double duration = 0.1) {
  return R"({"time": {"dt": )" + std::to_string(dt) + R"(, "duration": )" +
         std::to_string(duration) + R"(}, "backend": {"name": "box2d", "params": )" + params +
         R"(}, "particles": [)" + ball + R"(], "forces": [], "obstacles": )" + obstacles + "}";
}

std::string error_of(const std::string& text) {
  try {
    const Scene scene = parse_scene(text, "bad.json", ".");
    PluginLoader loader(plugin_search_dirs());
    Simulation sim(scene, loader);
    sim.step();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// Ball at x0 = 0 moving at vx = 2 towards the face x = 0.9 of a box, r = 0.05:
// t* = (0.9 - r) / vx = 0.425 s, n = (-1, 0), vn_after = e |vn_before| = 0.8 * 2 = 1.6.
TEST_CASE("ball against a wall: time of impact, normal, outgoing velocity") {
  const auto ev = box2d_events(kDir + "wall.json");
  REQUIRE(ev.size() == 1);
  CHECK(ev[0].obstacle == 0);
  CHECK(ev[0].t == Approx(0.425).margin(1e-4));
  CHECK(ev[0].normal[0] == Approx(-1.0).margin(1e-6));
  CHECK(ev[0].normal[1] == Approx(0.0).margin(1e-6));
  CHECK(ev[0].vn_before == Approx(-2.0).margin(1e-5));
  CHECK(ev[0].vn_after == Approx(1.6).margin(1e-4));
  CHECK(ev[0].point[0] == Approx(0.9).margin(1e-4));  // on the face
  const auto rep = crosscheck_file(kDir + "wall.json");
  CHECK(rep.pass);
}

// Path y = 0.03 meets |x - (0.5, 0)| = R + r = 0.15 at x = 0.5 - sqrt(0.15^2 - 0.03^2):
// t* = (x + 0.2) / 1.5, n = ((x - 0.5) / 0.15, 0.03 / 0.15), e = 1: vn_after = -vn_before.
TEST_CASE("ball against a circle: time of impact, normal, outgoing velocity") {
  const double x = 0.5 - std::sqrt(0.15 * 0.15 - 0.03 * 0.03);
  const auto ev = box2d_events(kDir + "circle.json");
  REQUIRE(ev.size() == 1);
  CHECK(ev[0].t == Approx((x + 0.2) / 1.5).margin(2e-4));
  // Box2D takes the normal where it found the overlap (up to |v| dt deep): angle ~ 1e-3
  CHECK(ev[0].normal[0] == Approx((x - 0.5) / 0.15).margin(2e-3));
  CHECK(ev[0].normal[1] == Approx(0.2).margin(2e-3));
  CHECK(ev[0].vn_before == Approx(-1.5 * (0.5 - x) / 0.15).margin(3e-3));
  CHECK(ev[0].vn_after == Approx(-ev[0].vn_before).margin(1e-4));
  CHECK(crosscheck_file(kDir + "circle.json").pass);
}

// Apex (0.5, 0), path y = 0.02: touch at x = 0.5 - sqrt(r^2 - 0.02^2), n = (x - 0.5, 0.02) / r.
TEST_CASE("ball against a polygon corner: vertex normal") {
  const double r = 0.05, x = 0.5 - std::sqrt(r * r - 0.02 * 0.02);
  const auto ev = box2d_events(kDir + "polygon_corner.json");
  REQUIRE(ev.size() == 1);
  CHECK(ev[0].t == Approx(x / 1.0).margin(2e-4));
  const double ang = std::atan2(ev[0].normal[1], ev[0].normal[0]) - std::atan2(0.02, x - 0.5);
  CHECK(std::abs(ang) < 1e-2);  // see polygon_corner.json: depth at detection * 0.4 / r
  CHECK(ev[0].vn_after == Approx(-ev[0].vn_before).margin(1e-4));
  CHECK(crosscheck_file(kDir + "polygon_corner.json").pass);
}

// L-shaped concave polygon (decomposed into convex pieces for Box2D): the ball hits
// x = 0.3 at t1 = 0.25 s and y = 0.1 at t2 = 0.3 s, and leaves with v = (-1, 1).
TEST_CASE("ball into a concave corner: two contacts, both components reversed") {
  const auto ev = box2d_events(kDir + "concave_corner.json");
  REQUIRE(ev.size() == 2);
  CHECK(ev[0].t == Approx(0.25).margin(1e-4));
  CHECK(ev[0].normal[0] == Approx(-1.0).margin(1e-6));
  CHECK(ev[1].t == Approx(0.30).margin(1e-4));
  CHECK(ev[1].normal[1] == Approx(1.0).margin(1e-6));
  CHECK(ev[1].vn_after == Approx(1.0).margin(1e-4));
  CHECK(crosscheck_file(kDir + "concave_corner.json").pass);
}

// A flipper swinging up at 20 rad/s hits a resting ball: relative to the contact point's
// velocity u = omega x (p - pivot), vn_after = -e vn_before (e = 0.5); the sdf backend is
// the reference for the time of impact and the normal.
TEST_CASE("moving flipper: kinematic contact agrees with sdf") {
  const auto ev = box2d_events(kDir + "flipper.json");
  REQUIRE(ev.size() >= 1);
  CHECK(ev[0].vn_before < -1.0);
  CHECK(ev[0].vn_after == Approx(-0.5 * ev[0].vn_before).epsilon(2e-2));
  const auto rep = crosscheck_file(kDir + "flipper.json");
  CHECK(rep.pass);
  const auto& c = rep.json["particles"][0]["contacts"][0];
  CHECK(std::abs(c["time_of_impact_difference"].get<double>()) < 1e-3);
  CHECK(c["normal_angle"].get<double>() < 1e-2);
}

TEST_CASE("the pinball table's agreement horizon is reported") {
  // The table's wall is the inside of a box united with a disc: a curved container wall
  // Box2D can only approximate, so the comparison opts in with curve_segments.
  const auto rep = crosscheck_file(
      PINSIM_CONFIG_DIR "/pinball.json",
      {R"(crosscheck={"params": {"box2d": {"curve_segments": 256, "rest_speed": 0.005}}})"});
  const double h = rep.json["particles"][0]["agreement_horizon"].get<double>();
  INFO(rep.table);
  CHECK(h > 0.5);  // the plunger shot agrees; measured 0.91 s (README)
  CHECK(h <= 6.0);
  CHECK(rep.json["energy"].contains("box2d"));
  CHECK(rep.table.find("horizon") != std::string::npos);
}

TEST_CASE("the shipped pinball scene's own crosscheck settings pass") {
  // configs/pinball.json asks for 1 mm agreement over 0.5 s, normals within 0.02 rad
  // (Box2D's 256-segment wall top is within pi/256 of the true normal).
  const auto rep = crosscheck_file(PINSIM_CONFIG_DIR "/pinball.json");
  INFO(rep.table);
  CHECK(rep.pass);
  CHECK(rep.json["particles"][0]["agreement_horizon"].get<double>() >= 0.5);
}

TEST_CASE("features Box2D cannot express are errors naming the obstacle and feature") {
  const std::string ball = R"({"x": [0, 0], "v": [1, 0], "mass": 1, "radius": 0.05})";
  SECTION("arc") {
    const std::string e = error_of(scene_text(
        R"([{"id": "ring", "shape": {"type": "arc", "center": [0, 0], "radius": 1, "start_angle": 0, "end_angle": 3, "thickness": 0.1}}])",
        ball));
    CHECK_THAT(e, Contains("bad.json: obstacles[0].shape") && Contains("'ring'") &&
                      Contains("arc") && Contains("unsupported by box2d"));
  }
  SECTION("subtraction inside a union") {
    const std::string e = error_of(scene_text(
        R"([{"id": "w", "shape": {"type": "box", "center": [2, 0], "half_size": [0.1, 1]}},
            {"id": "bite", "shape": {"type": "union", "shapes": [{"type": "box", "center": [0, 3], "half_size": [1, 1]},
             {"type": "subtraction", "shapes": [{"type": "box", "center": [0, -3], "half_size": [1, 1]},
                                                {"type": "circle", "center": [0, -2], "radius": 0.5}]}]}}])",
        ball));
    CHECK_THAT(e, Contains("obstacles[1].shape.shapes[1]") && Contains("'bite'") &&
                      Contains("subtraction"));
  }
  SECTION("intersection (a smooth or sharp blend of SDFs)") {
    const std::string e = error_of(scene_text(
        R"([{"id": "lens", "shape": {"type": "intersection", "shapes": [{"type": "circle", "center": [1, 0], "radius": 0.5},
                                                                      {"type": "circle", "center": [1.5, 0], "radius": 0.5}]}}])",
        ball));
    CHECK_THAT(e, Contains("'lens'") && Contains("intersection"));
  }
  SECTION("inside of a circle without curve_segments") {
    const std::string e = error_of(scene_text(
        R"([{"id": "bowl", "shape": {"type": "inside", "shape": {"type": "circle", "center": [0, 0], "radius": 1}}}])",
        ball));
    CHECK_THAT(e, Contains("obstacles[0].shape.shape") && Contains("'bowl'") &&
                      Contains("curve_segments"));
  }
  SECTION("the sdf parser's own errors come through unchanged") {
    const std::string e = error_of(scene_text(
        R"([{"id": "c", "shape": {"type": "circle", "center": [0, 0], "radius": -1}}])", ball));
    CHECK_THAT(e, Contains("bad.json: obstacles[0].shape.radius: must be > 0"));
  }
}

TEST_CASE("a bad contacts block is the same error on box2d as on sdf (one parser)") {
  const std::string ball = R"({"x": [0, 0], "v": [1, 0], "mass": 1, "radius": 0.05})";
  std::string text = scene_text("[]", ball);
  text.insert(text.size() - 1, R"(, "contacts": {"particles": true, "restitution": 1.5})");
  std::string on_sdf = text;
  on_sdf.replace(on_sdf.find("\"box2d\""), 7, "\"sdf\"");
  const std::string e = error_of(text);
  CHECK_THAT(e, Contains("bad.json: contacts.restitution: must be in [0, 1], got 1.5"));
  CHECK(e == error_of(on_sdf));
}

TEST_CASE("one obstacle reader: box2d and sdf give the same JSON-path errors") {
  const std::string ball = R"({"x": [5, 5], "v": [1, 0], "mass": 1, "radius": 0.05})";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"([{"id": "p", "shape": {"type": "polygon", "points": [[0, 0], [1, 0]]}}])",
       "bad.json: obstacles[0].shape.points: need at least 3 points, got 2"},
      {R"([{"id": "u", "shape": {"type": "union", "shapes": [{"type": "blob"}]}}])",
       "bad.json: obstacles[0].shape.shapes[0].type: unknown shape type 'blob'"},
      {R"([{"id": "b", "shape": {"type": "box", "center": [0, 0], "half_size": [1, 1], "angel": 1}}])",
       "bad.json: obstacles[0].shape.angel: unknown key"},
      {R"([{"id": "t", "shape": {"type": "inside", "shape": {"type": "tapered_capsule", "a": [0, 0], "b": [1, 0], "radius_a": 2, "radius_b": 0.1}}}])",
       "bad.json: obstacles[0].shape.shape.b: need |radius_a - radius_b| < |b - a|"},
      {R"([{"id": "f", "shape": {"type": "circle", "center": [0, 0], "radius": 1}, "motion": {"type": "flipper", "pivot": [0, 0]}}])",
       "bad.json: obstacles[0].motion.rest_angle: required number is missing"},
      {R"([{"id": "d", "shape": {"type": "circle", "center": [0, 0], "radius": 1}}, {"id": "d", "shape": {"type": "circle", "center": [3, 0], "radius": 1}}])",
       "bad.json: obstacles[1].id: duplicate obstacle id \"d\""},
  };
  for (const auto& [obstacles, message] : cases) {
    const std::string box2d = scene_text(obstacles, ball);
    std::string sdf = box2d;
    sdf.replace(sdf.find("\"box2d\""), 7, "\"sdf\"");
    INFO(obstacles);
    CHECK_THAT(error_of(box2d), Contains(message));
    CHECK_THAT(error_of(sdf), Contains(message));
  }
}

TEST_CASE("one obstacle reader: box2d builds its fixtures from the compiled shape tree") {
  // a transformed union of every primitive Box2D expresses, and a clockwise polygon: the
  // pieces come from the tree (ends as given, polygon counter-clockwise)
  const nlohmann::json scene = nlohmann::json::parse(R"({"obstacles": [{"id": "all", "shape":
    {"type": "union", "transform": {"translate": [1, 2], "rotate": 0.5}, "shapes": [
      {"type": "circle", "center": [0, 0], "radius": 0.5},
      {"type": "capsule", "a": [1, 0], "b": [2, 0], "radius": 0.1},
      {"type": "polygon", "points": [[0, 3], [1, 4], [1, 3]]},
      {"type": "rounded_box", "center": [3, 3], "half_size": [0.5, 0.4], "corner_radius": 0.1}]}}]})");
  const sdf::ObstacleField field(scene, "t.json", {}, 0);
  const auto pieces = box2d::build_pieces(field.obstacle(0).shape, "t.json", "obstacles[0].shape",
                                          "all", box2d::BuildOptions{});
  REQUIRE(pieces.size() == 4);
  const Transform x{Rotation::from_angle(0.5), Vec2(1, 2)};
  CHECK(pieces[0].kind == box2d::Piece::Kind::kCircle);
  CHECK(pieces[0].v[0] == x.apply(Vec2(0, 0)));
  CHECK(pieces[1].kind == box2d::Piece::Kind::kEdge);
  CHECK(pieces[1].v[0] == x.apply(Vec2(1, 0)));
  CHECK(pieces[1].v[1] == x.apply(Vec2(2, 0)));
  CHECK(pieces[1].radius == 0.1);
  CHECK(pieces[2].kind == box2d::Piece::Kind::kPolygon);
  CHECK(pieces[2].v ==
        std::vector<Vec2>{x.apply(Vec2(1, 3)), x.apply(Vec2(1, 4)), x.apply(Vec2(0, 3))});
  CHECK(pieces[3].kind == box2d::Piece::Kind::kPolygon);
  CHECK(pieces[3].radius == 0.1);
}

// Box2D 2.4.1 caps each step's travel at b2_maxTranslation = 2 units and would silently
// slow a faster body. At r = 0.05 the automatic scale is 1 / r = 20 units per metre; at
// 30 m/s and dt = 0.01 a step is 0.3 m = 6 units: an error. With length_scale 5 a step is
// 1.5 units: the ball keeps its speed exactly (x = 30 t in free flight, |v| = 30 after
// an e = 1 wall).
TEST_CASE("a ball faster than Box2D's speed cap is reported or handled by the scale") {
  const std::string ball = R"({"x": [0, 0], "v": [30, 0], "mass": 1, "radius": 0.05})";
  const std::string wall =
      R"([{"id": "wall", "shape": {"type": "box", "center": [2.6, 0], "half_size": [0.1, 1]}}])";
  const std::string e = error_of(scene_text(wall, ball, "{}", 0.01, 0.2));
  CHECK_THAT(e, Contains("b2_maxTranslation") && Contains("length_scale between 0.025 and 6.667"));

  const Scene scene =
      parse_scene(scene_text(wall, ball, R"({"length_scale": 5})", 0.01, 0.2), "fast.json", ".");
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(scene, loader);
  std::vector<pinsim_event> events;  // each step's events are its own: collect them
  for (int k = 0; k < 5; ++k) {
    sim.step();
    events.insert(events.end(), sim.events().begin(), sim.events().end());
  }
  CHECK(sim.state().x(0, 0) == Approx(1.5).epsilon(1e-12));
  for (int k = 0; k < 15; ++k) {
    sim.step();
    events.insert(events.end(), sim.events().begin(), sim.events().end());
  }
  CHECK(sim.state().v.col(0).norm() == Approx(30.0).epsilon(1e-6));
  CHECK(sim.state().v(0, 0) < 0.0);
  REQUIRE(events.size() >= 1);
  // t* = (2.5 - 0.05) / 30
  CHECK(events[0].t == Approx(2.45 / 30.0).margin(1e-4));
}

// The speed check looks at every particle and names the fastest. Here the wall is 0.0003
// thick: Box2D needs its edges longer than b2_linearSlop = 0.005 units, so length_scale >
// 0.005 / 0.0003 = 16.67, while 300 m/s at dt = 0.01 needs length_scale < 2 / 3: no scale
// works, and the largest time step that would is 2 / (300 * 16.67) = 4e-4 s.
TEST_CASE("box2d's speed refusal names the fastest particle and says when no scale works") {
  const std::string balls = R"({"x": [0, 0], "v": [30, 0], "mass": 1, "radius": 0.05},
                               {"x": [0, 1], "v": [300, 0], "mass": 1, "radius": 0.05})";
  const std::string thin =
      R"([{"id": "thin", "shape": {"type": "box", "center": [2.6, 0], "half_size": [0.00015, 1]}}])";
  const std::string e = error_of(scene_text(thin, balls, "{}", 0.01, 0.2));
  CHECK_THAT(e, Contains("particle 1 at t = 0: speed 300 moves it 60 Box2D units in one step") &&
                    Contains("2 particle(s) over") &&
                    Contains("no length scale works at dt = 0.01: below 0.6667 the thinnest wall "
                             "(an edge of 0.0003 in obstacle 'thin') is shorter than "
                             "b2_linearSlop; use a time step below 0.0004"));
}

TEST_CASE("concave polygons decompose into convex pieces of at most 8 vertices") {
  // A comb: 4 teeth, 20 vertices, counter-clockwise; area = 4 * 0.1 * 1 + 1.5 * 0.2 = 0.7.
  std::vector<Vec2> comb = {{0, 0}, {1.5, 0}, {1.5, 0.2}};
  for (int k = 3; k >= 0; --k) {
    const double x0 = 0.1 + 0.4 * k;
    comb.push_back({x0 + 0.1, 0.2});
    comb.push_back({x0 + 0.1, 1.2});
    comb.push_back({x0, 1.2});
    comb.push_back({x0, 0.2});
  }
  comb.push_back({0, 0.2});
  const auto parts = box2d::convex_decompose(comb, 8);
  double area = 0.0;
  for (const auto& p : parts) {
    CHECK(p.size() <= 8);
    CHECK(box2d::is_convex(p));
    for (std::size_t i = 0; i < p.size(); ++i) {
      const Vec2 &a = p[i], &b = p[(i + 1) % p.size()];
      area += 0.5 * (a.x() * b.y() - a.y() * b.x());
    }
  }
  CHECK(area == Approx(0.7).epsilon(1e-12));
  CHECK(parts.size() < comb.size() - 2);  // merged, not just triangles
}
