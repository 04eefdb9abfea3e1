// The benchmarks' cloth: n x n particles (spacing 1 cm, 10 kg in all, radius 2 mm), top row
// pinned, damped springs on the edges (ks 50 N/m, kd 0.01 N s/m) and shears (ks 20, kd 0.005),
// gravity, dt = 1 ms, on the sdf backend with no obstacles. pinsim_bench_cloth and
// pinsim_bench_output time the same scene.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace pinsim::bench {

inline nlohmann::json cloth_scene(int n, const std::string& integrator = "symplectic_euler") {
  nlohmann::json pin = nlohmann::json::array();
  for (int i = 0; i < n; ++i) pin.push_back((n - 1) * n + i);  // the top row
  nlohmann::json doc = nlohmann::json::parse(R"({"name": "cloth",
    "time": {"dt": 0.001, "duration": 1.0}, "backend": {"name": "sdf"},
    "bodies": [{"type": "grid_blob", "name": "cloth", "origin": [0, 0],
                "spacing": 0.01, "total_mass": 10.0, "radius": 0.002}],
    "forces": [{"type": "gravity", "params": {"g": [0, -9.81]}},
               {"type": "damped_spring", "params": {"ks": 50, "kd": 0.01},
                "elements": {"body": "cloth", "set": "edges"}},
               {"type": "damped_spring", "params": {"ks": 20, "kd": 0.005},
                "elements": {"body": "cloth", "set": "shear"}}]})");
  doc["integrator"] = integrator;
  doc["bodies"][0]["nx"] = n;
  doc["bodies"][0]["ny"] = n;
  doc["bodies"][0]["pin"] = pin;
  return doc;
}

}  // namespace pinsim::bench
