// Time integrators: each splits a step into force "kicks" and the backend's "drift".
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <pinsim/state.hpp>
#include <string>
#include <vector>

namespace pinsim {

class Simulation;

class Integrator {
 public:
  virtual ~Integrator() = default;
  /// Advances sim.state() by dt.
  virtual void step(Simulation& sim, double dt) = 0;
  /// Figures of the integrator's own work for summary.json, or null (the default).
  virtual nlohmann::json stats() const { return nullptr; }
};

/// The integrator called `name`; throws std::invalid_argument listing the known ones.
std::unique_ptr<Integrator> make_integrator(const std::string& name);
/// Names of all integrators.
std::vector<std::string> integrator_names();

}  // namespace pinsim
