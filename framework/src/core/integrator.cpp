#include "core/integrator.hpp"

#include <functional>
#include <map>
#include <stdexcept>

#include "core/integrators.hpp"

namespace pinsim {
namespace {

const std::map<std::string, std::function<std::unique_ptr<Integrator>()>>& registry() {
  static const std::map<std::string, std::function<std::unique_ptr<Integrator>()>> r = {
      {"symplectic_euler", [] { return make_symplectic_euler(); }},
      {"velocity_verlet", [] { return make_velocity_verlet(); }},
      {"explicit_euler", [] { return make_explicit_euler(); }},
      {"rk4", [] { return make_rk4(); }},
      {"implicit_euler", [] { return make_implicit_euler(); }},
  };
  return r;
}

}  // namespace

std::vector<std::string> integrator_names() {
  std::vector<std::string> out;
  for (const auto& [name, _] : registry()) out.push_back(name);
  return out;
}

std::unique_ptr<Integrator> make_integrator(const std::string& name) {
  auto it = registry().find(name);
  if (it == registry().end()) {
    std::string known;
    for (const auto& n : integrator_names()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown integrator '" + name + "' (known: " + known + ")");
  }
  return it->second();
}

}  // namespace pinsim
