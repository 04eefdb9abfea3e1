// The small bench config both sweep tests run: the harmonic oscillator x'' = -9 x (closed
// form, omega = 3), two integrators x four dt = 8 points.
#pragma once

inline constexpr const char* kBench = R"({
  "repeats": 1,
  "integrators": ["symplectic_euler", "velocity_verlet"],
  "cases": [{"name": "oscillator",
    "scene": {"time": {"dt": 0.01, "duration": 2.0},
              "particles": [{"x": [0, 0], "pinned": true}, {"x": [1, 0], "v": [0, 1.5], "mass": 2.0}],
              "forces": [{"type": "linear_spring", "params": {"k": 18.0, "rest_length": 0.0},
                          "elements": [[0, 1]]}]},
    "answer": {"type": "harmonic", "particle": 1, "omega": 3.0},
    "dt": [0.01, 0.005, 0.0025, 0.00125]}]
})";
