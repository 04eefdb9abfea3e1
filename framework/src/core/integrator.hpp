// Time integrators: each splits a step into force "kicks" and the backend's "drift".
#pragma once

#include <memory>
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
};

/// The integrator called `name`; throws std::invalid_argument listing the known ones.
std::unique_ptr<Integrator> make_integrator(const std::string& name);
/// Names of all integrators.
std::vector<std::string> integrator_names();

}  // namespace pinsim
