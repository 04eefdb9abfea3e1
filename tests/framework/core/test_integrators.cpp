// Time integrators against closed forms on a projectile (uniform gravity, no obstacles).
#include <catch2/catch.hpp>
#include <cmath>

#include "core/scene.hpp"
#include "core/simulation.hpp"

using namespace pinsim;

namespace {

// One particle at the origin thrown with (vx, vy) under g = (0, -g), for T seconds.
Scene projectile(double dt, double T, const std::string& integrator) {
  const std::string text = R"({
    "time": {"dt": )" + std::to_string(dt) +
                           R"(, "duration": )" + std::to_string(T) + R"(},
    "integrator": ")" + integrator +
                           R"(",
    "particles": [{"x": [0, 0], "v": [3, 7], "mass": 2.0}],
    "forces": [{"type": "gravity", "params": {"g": [0, -9.81]}}]
  })";
  return parse_scene(text, "projectile.json", ".");
}

State run(const Scene& s) {
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(s, loader);
  for (uint64_t i = 0; i < s.steps(); ++i) sim.step();
  return sim.state();
}

}  // namespace

TEST_CASE("symplectic Euler: projectile y error after T is exactly -g h T / 2") {
  // v_n = v0 - n g h,  y_N = h sum_{n=1..N} v_n = v0 T - g h^2 N (N+1) / 2
  //                        = (v0 T - g T^2 / 2) - g h T / 2.
  const double g = 9.81, vy0 = 7.0, T = 1.0;
  for (double h : {0.01, 0.005, 0.0025}) {
    const State s = run(projectile(h, T, "symplectic_euler"));
    const double exact = vy0 * T - 0.5 * g * T * T;
    CHECK(s.x(1, 0) - exact == Approx(-g * h * T / 2).epsilon(1e-9));
    CHECK(s.x(0, 0) == Approx(3.0 * T).epsilon(1e-12));      // x = vx T, no force along x
    CHECK(s.v(1, 0) == Approx(vy0 - g * T).epsilon(1e-12));  // v is exact for a constant force
    CHECK(s.t == Approx(T).epsilon(1e-15));
  }
}

TEST_CASE("velocity Verlet: projectile exact to rounding") {
  // For a constant force, kick/2-drift-kick/2 reproduces y = v0 t - g t^2 / 2 exactly.
  const double g = 9.81, vy0 = 7.0, T = 1.0;
  const State s = run(projectile(0.01, T, "velocity_verlet"));
  CHECK(s.x(1, 0) == Approx(vy0 * T - 0.5 * g * T * T).margin(1e-12));
  CHECK(s.x(0, 0) == Approx(3.0 * T).margin(1e-12));
  CHECK(s.v(1, 0) == Approx(vy0 - g * T).margin(1e-12));
}

TEST_CASE("pinned particles neither move nor feel gravity") {
  const std::string text = R"({
    "time": {"dt": 0.01, "duration": 0.5},
    "particles": [{"x": [1, 2], "pinned": true}, {"x": [0, 0]}],
    "forces": [{"type": "gravity"}]
  })";
  const State s = run(parse_scene(text, "pinned.json", "."));
  CHECK(s.x(0, 0) == 1.0);
  CHECK(s.x(1, 0) == 2.0);
  CHECK(s.x(1, 1) < 0.0);
}
