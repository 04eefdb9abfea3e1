#include "core/integrator.hpp"

#include <functional>
#include <map>
#include <stdexcept>

#include "core/integrators.hpp"

namespace pinsim {
namespace {

using Factory = std::function<std::unique_ptr<Integrator>(const XpbdSettings&)>;

const std::map<std::string, Factory>& registry() {
  static const std::map<std::string, Factory> r = {
      {"symplectic_euler", [](const XpbdSettings&) { return make_symplectic_euler(); }},
      {"velocity_verlet", [](const XpbdSettings&) { return make_velocity_verlet(); }},
      {"explicit_euler", [](const XpbdSettings&) { return make_explicit_euler(); }},
      {"rk4", [](const XpbdSettings&) { return make_rk4(); }},
      {"implicit_euler", [](const XpbdSettings&) { return make_implicit_euler(); }},
      {"xpbd", [](const XpbdSettings& x) { return make_xpbd(x); }},
  };
  return r;
}

}  // namespace

std::vector<std::string> integrator_names() {
  std::vector<std::string> out;
  for (const auto& [name, _] : registry()) out.push_back(name);
  return out;
}

std::unique_ptr<Integrator> make_integrator(const std::string& name, const XpbdSettings& xpbd) {
  auto it = registry().find(name);
  if (it == registry().end()) {
    std::string known;
    for (const auto& n : integrator_names()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown integrator '" + name + "' (known: " + known + ")");
  }
  return it->second(xpbd);
}

}  // namespace pinsim
