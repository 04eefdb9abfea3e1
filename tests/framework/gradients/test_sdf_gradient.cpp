// Gradients of runs through the sdf backend's collisions (time-of-impact splitting, the
// normal and its derivatives at the impact, particle-particle contacts, materials): against
// closed forms and central differences of whole runs with --set.
#include <catch2/catch.hpp>
#include <cmath>

#include "core/input_error.hpp"
#include "gradients/scene_gradient.hpp"
#include "whole_runs.hpp"

using namespace pinsim;
using namespace pinsim::grad;
using namespace pinsim::grad::testing;

namespace {

// A ball dropped from rest at height h0 = 1 onto a floor (restitution 0.8), symplectic Euler
// with h = 0.01: it reaches the contact offset L = r + depth_min during step 44 and is still
// rising at the end (t = 0.6 s).
const char* kFloorBounce = R"({
  "time": {"dt": 0.01, "duration": 0.6},
  "integrator": "symplectic_euler",
  "backend": {"name": "sdf"},
  "particles": [{"x": [0.0, 1.0], "v": [0.0, 0.0], "mass": 1.0, "radius": 0.05}],
  "forces": [{"type": "gravity", "params": {"g": [0.0, -9.81]}}],
  "obstacles": [{"id": "floor", "shape": {"type": "half_plane", "point": [0, 0], "normal": [0, 1]},
                 "material": {"restitution": 0.8}}]
})";

// A ball launched under gravity against the underside of a box (t = 0.138 s), then a circle
// (t = 0.296 s); restitutions 0.9 (circle), 0.7 (box) and 0.6 (a floor it does not reach).
const char* kTwoObstacles = R"({
  "time": {"dt": 0.002, "duration": 0.6},
  "integrator": "symplectic_euler",
  "backend": {"name": "sdf"},
  "particles": [{"x": [0.0, 0.3], "v": [2.0, 2.5], "mass": 1.0, "radius": 0.05}],
  "forces": [{"type": "gravity", "params": {"g": [0.0, -9.81]}}],
  "obstacles": [
    {"id": "post", "shape": {"type": "circle", "center": [0.6, 0.1], "radius": 0.15},
     "material": {"restitution": 0.9}},
    {"id": "block", "shape": {"type": "box", "center": [0.35, 0.65], "half_size": [0.25, 0.05]},
     "material": {"restitution": 0.7}},
    {"id": "floor", "shape": {"type": "half_plane", "point": [0, -0.5], "normal": [0, 1]},
     "material": {"restitution": 0.6}}
  ]
})";

// Two equal balls head-on on the x axis, elastic particle-particle contact, no forces: ball 0
// from a = -0.5 at p = 1, ball 1 from b = 0.3 at q = -0.2, radius r = 0.05 each.
const char* kTwoBalls = R"({
  "time": {"dt": 0.01, "duration": 1.0},
  "integrator": "symplectic_euler",
  "backend": {"name": "sdf"},
  "contacts": {"particles": true, "restitution": 1.0},
  "particles": [{"x": [-0.5, 0.0], "v": [1.0, 0.0], "mass": 1.0, "radius": 0.05},
                {"x": [0.3, 0.0], "v": [-0.2, 0.0], "mass": 1.0, "radius": 0.05}],
  "forces": []
})";

const PathGradient& path(const GradientReport& r, const std::string& p) {
  for (const PathGradient& g : r.paths)
    if (g.wrt.path == p) return g;
  FAIL("no path " << p);
  return r.paths.front();
}

}  // namespace

TEST_CASE("sdf gradient: a ball bouncing on a floor, d(final height)/d(h0) = -e",
          "[gradients][sdf]") {
  // Symplectic Euler: v_n = -g h n and y_n = h0 - g h^2 n (n + 1) / 2 do not depend on h0 until
  // the bounce, so dy/dh0 = 1 there. In the bounce step the velocity w = v_(k-1) - g h is
  // reached at the time of impact tau = (y_(k-1) - L) / -w, so d tau / d h0 = 1 / -w, and the
  // step ends at y_k = L - e w (h - tau): d y_k / d h0 = e w d tau / d h0 = -e. Afterwards the
  // velocities again do not depend on h0: d y(T) / d h0 = -e = -0.8.
  // Without the split (the impulse taken at a time that does not move with the state, tau
  // fixed: y_k = y_(k-1) + w tau - e w (h - tau)), d y(T) / d h0 would be +1: the wrong sign.
  const std::string file = scene_file("grad_floor", kFloorBounce);
  const GradientReport r =
      gradient(file, {}, "final:0:y", {"particles[0].x", "particles[0].v"}, "");
  CHECK(r.findings_count == 0);
  CHECK(r.impacts == 1);
  const Eigen::VectorXd gx = path(r, "particles[0].x").gradient;
  CHECK(gx[0] == Approx(0.0).margin(1e-12));
  CHECK(gx[1] == Approx(-0.8).epsilon(1e-9));
  // and the same against whole runs (the floor is flat: the march lands on the offset exactly)
  check_against_runs(file, {}, "final:0:y", {"particles[0].x", "particles[0].v"}, "");
  check_against_runs(file, {}, "final:0:vy",
                     {"particles[0].x", "obstacles[0].material.restitution"}, "");
}

TEST_CASE("sdf gradient: two equal balls head-on, elastic: the (1, 0, 1, 0) pattern",
          "[gradients][sdf]") {
  // 1D: the hit at tau = (b - a - 2r) / (p - q) exchanges the velocities, so
  //   x_1(T) = b + q tau + p (T - tau) = a + 2r + p T,  v_1(T) = p,
  //   x_0(T) = b - 2r + q T,                            v_0(T) = q.
  // d x_1(T) / d(a, b) = (1, 0), d v_1(T) / d(p, q) = (1, 0); off the axis the normal turns, but
  // only to second order in the x components. T = 1 s.
  const std::string file = scene_file("grad_two_balls", kTwoBalls);
  const std::vector<std::string> wrt = {"particles[0].x", "particles[1].x", "particles[0].v",
                                        "particles[1].v"};
  const GradientReport x1 = gradient(file, {}, "final:1:x", wrt, "");
  CHECK(x1.findings_count == 0);
  CHECK(x1.impacts == 2);  // the hit's velocity change of each ball
  auto near = [](const Eigen::VectorXd& g, double gx, double gy) {
    INFO(g.transpose());
    CHECK(g[0] == Approx(gx).margin(1e-12));
    CHECK(g[1] == Approx(gy).margin(1e-12));
  };
  near(path(x1, "particles[0].x").gradient, 1.0, 0.0);
  near(path(x1, "particles[1].x").gradient, 0.0, 0.0);
  near(path(x1, "particles[0].v").gradient, 1.0, 0.0);  // T = 1 s
  near(path(x1, "particles[1].v").gradient, 0.0, 0.0);
  const GradientReport v1 = gradient(file, {}, "final:1:vx", wrt, "");
  near(path(v1, "particles[0].v").gradient, 1.0, 0.0);
  near(path(v1, "particles[1].v").gradient, 0.0, 0.0);
  near(path(v1, "particles[0].x").gradient, 0.0, 0.0);
  const GradientReport x0 = gradient(file, {}, "final:0:x", wrt, "");
  near(path(x0, "particles[1].x").gradient, 1.0, 0.0);
  near(path(x0, "particles[1].v").gradient, 1.0, 0.0);
  near(path(x0, "particles[0].x").gradient, 0.0, 0.0);
  // off-axis components through the turning normal, against whole runs
  check_against_runs(file, {}, "final:1:y", wrt, "");
  check_against_runs(file, {}, "target:0:0.2,0.1", wrt, "");
}

TEST_CASE("sdf gradient: a ball off a box and a circle against whole runs", "[gradients][sdf]") {
  const std::string file = scene_file("grad_obstacles", kTwoObstacles);
  const std::vector<std::string> wrt = {
      "particles[0].x", "particles[0].v", "obstacles[0].material.restitution",
      "obstacles[1].material.restitution", "obstacles[2].material.restitution"};
  const GradientReport r = gradient(file, {}, "target:0:1.2,0.5", wrt, "");
  CHECK(r.findings_count == 0);
  CHECK(r.impacts == 2);
  // Central differences with step 1e-5 (truncation e^2 L''' / 6, ~1e-8 relative here);
  // the march stops within march_tolerance of the offset, which moves positions by ~1e-12
  // as the state changes, ~1e-7 in the differences.
  for (const char* loss : {"final:0:x", "final:0:vy", "target:0:1.2,0.5"})
    check_against_runs(file, {}, loss, wrt, "", 1e-6, 1e-5);
  for (const char* integrator : {"velocity_verlet", "implicit_euler"})
    check_against_runs(file, {}, "target:0:1.2,0.5", wrt, integrator, 1e-6, 1e-5);
}

TEST_CASE("sdf gradient: a resting contact and materials without a recording backend are said",
          "[gradients][sdf]") {
  // a ball resting on the floor: an impulse inside the contact band every step
  const std::string file = scene_file("grad_resting", kFloorBounce);
  const GradientReport r =
      gradient(file, {"particles[0].x=[0,0.05001]"}, "final:0:y", {"particles[0].x"}, "");
  CHECK(r.findings_count > 0);
  CHECK_FALSE(r.to_json()["differentiable"].get<bool>());
  CHECK(r.to_json()["findings"][0]["kind"] == "resting");
  // a material path with the none backend is refused, naming the path
  CHECK_THROWS_WITH(gradient(PINSIM_SOURCE_DIR "/configs/projectile.json", {}, "final:0:x",
                             {"obstacles[0].material.restitution"}, ""),
                    Catch::Contains("--wrt obstacles[0].material.restitution") &&
                        Catch::Contains("backend 'none' does not"));
  CHECK_THROWS_WITH(gradient(file, {}, "final:0:x", {"obstacles[3].material.restitution"}, ""),
                    Catch::Contains("1 obstacles, no index 3"));
  CHECK_THROWS_WITH(gradient(file, {}, "final:0:x", {"obstacles[0].material.colour"}, ""),
                    Catch::Contains("expected obstacles[K].material.restitution"));
}

TEST_CASE("sdf gradient: a ball hit by a rotating flipper against whole runs", "[gradients][sdf]") {
  // The flipper (pivot at the origin) is pressed at t = 0.03 s and turns up at 25 rad/s; the
  // ball meets it at t = 0.048 s while it turns: the impulse uses the flipper's velocity at the
  // contact point, and the time of impact, the normal and that velocity all move with the
  // state (d n / d t, d u / d q, d u / d t of the rotation).
  const std::string file = scene_file("grad_flipper", R"({
    "time": {"dt": 0.001, "duration": 0.12},
    "integrator": "symplectic_euler",
    "backend": {"name": "sdf"},
    "particles": [{"x": [0.05, 0.08], "v": [0.0, -1.0], "mass": 1.0, "radius": 0.0135}],
    "forces": [{"type": "gravity", "params": {"g": [0.0, -9.81]}}],
    "obstacles": [
      {"id": "flipper",
       "shape": {"type": "tapered_capsule", "a": [0, 0], "b": [0.075, 0], "radius_a": 0.012,
                 "radius_b": 0.006},
       "material": {"restitution": 0.5},
       "motion": {"type": "flipper", "pivot": [0.0, 0.0], "rest_angle": -0.5,
                  "raised_angle": 0.45, "angular_speed": 25.0, "return_angular_speed": 10.0,
                  "input": "left"}}],
    "inputs": [{"t": 0.03, "input": "left", "action": "press"}]
  })");
  const std::vector<std::string> wrt = {"particles[0].x", "particles[0].v",
                                        "obstacles[0].material.restitution"};
  const GradientReport r = gradient(file, {}, "final:0:y", wrt, "");
  CHECK(r.findings_count == 0);
  CHECK(r.impacts == 1);
  for (const char* loss : {"final:0:x", "final:0:y", "final:0:vx"})
    check_against_runs(file, {}, loss, wrt, "", 1e-6, 1e-5);
}

TEST_CASE("sdf gradient: capped marches and sliding contacts are said", "[gradients][sdf]") {
  const std::string box = PINSIM_SOURCE_DIR "/configs/empty_box.json";
  // at 50 units/s a step of 0.05 s crosses the box (0.9 wide) several times, with one impulse
  // allowed per step
  const GradientReport cap = gradient(box,
                                      {"time.dt=0.05", "time.duration=0.2",
                                       "backend.params.max_collisions=1", "particles[0].v=[50,0]"},
                                      "final:0:x", {"particles[0].v"}, "");
  REQUIRE(cap.findings_count > 0);
  CHECK(cap.to_json()["findings"][0]["kind"] == "cap_hit");
  CHECK_FALSE(cap.to_json()["differentiable"].get<bool>());
  // a ball sliding along the box's top wall inside the contact band (the offset is 0.5 - r -
  // depth_min = 0.449999, the band 1e-7 above it): a nearby run may hit the wall
  const GradientReport slide =
      gradient(box, {"particles[0].x=[0,0.44999895]"}, "final:0:x", {"particles[0].v"}, "");
  REQUIRE(slide.findings_count > 0);
  CHECK(slide.to_json()["findings"][0]["kind"] == "touch");
  CHECK(slide.findings.size() <= GradientReport::kMaxFindings);
}
