#include "core/plugin_table_check.hpp"

#include <cstring>
#include <set>
#include <string_view>
#include <vector>

namespace pinsim {
namespace {

/// One capability flag and whether the function it announces is there.
struct Pairing {
  uint32_t flag;
  const char* flag_name;
  bool present;
  const char* function;
};

void check_pairs(uint32_t caps, const std::vector<Pairing>& pairs, std::vector<std::string>& out) {
  for (const auto& p : pairs) {
    const bool declared = (caps & p.flag) != 0;
    if (declared && !p.present)
      out.push_back(std::string("declares ") + p.flag_name + " but its " + p.function +
                    " function is NULL");
    else if (!declared && p.present)
      out.push_back(std::string("provides the ") + p.function + " function but does not declare " +
                    p.flag_name);
  }
}

void check_params(const pinsim_plugin& t, std::vector<std::string>& out) {
  if (t.n_params > kMaxPluginParams) {
    out.push_back("declares " + std::to_string(t.n_params) + " parameters (at most " +
                  std::to_string(kMaxPluginParams) + ")");
    return;
  }
  if (t.n_params > 0 && t.params == nullptr) {
    out.push_back("declares " + std::to_string(t.n_params) +
                  " parameters but its params array "
                  "is NULL");
    return;
  }
  std::set<std::string_view> names;
  for (uint32_t i = 0; i < t.n_params; ++i) {
    const pinsim_param& p = t.params[i];
    const std::string at = "parameter " + std::to_string(i);
    if (p.name == nullptr || p.name[0] == '\0') {
      out.push_back(at + " has no name");
      continue;
    }
    const std::string named = at + " '" + p.name + "'";
    if (!names.insert(p.name).second) out.push_back(named + " is declared twice");
    if (p.type < PINSIM_PARAM_REAL || p.type > PINSIM_PARAM_VEC2)
      out.push_back(named + " has an unknown type " + std::to_string(p.type));
    if (p.units == nullptr) out.push_back(named + " has NULL units (use \"1\" for none)");
    if (p.doc == nullptr) out.push_back(named + " has a NULL doc string");
  }
}

}  // namespace

std::string plugin_table_problems(const pinsim_plugin& t) {
  std::vector<std::string> out;
  if (t.version == nullptr) out.push_back("its version string is NULL");
  if (t.doc == nullptr) out.push_back("its doc string is NULL");
  check_params(t, out);
  const uint32_t caps = t.capabilities;
  if (t.kind == PINSIM_KIND_FORCE) {
    if (t.arity > kMaxForceArity)
      out.push_back("declares arity " + std::to_string(t.arity) + " (at most " +
                    std::to_string(kMaxForceArity) + ", or PINSIM_ARITY_VARIABLE)");
    // One add_jacobians serves both Jacobians: it must be there when either is declared.
    const bool jac = (caps & (PINSIM_CAP_DFDX | PINSIM_CAP_DFDV)) != 0;
    if (jac && t.force.add_jacobians == nullptr)
      out.push_back(std::string("declares ") +
                    ((caps & PINSIM_CAP_DFDX) ? "PINSIM_CAP_DFDX" : "PINSIM_CAP_DFDV") +
                    " but its add_jacobians function is NULL");
    else if (!jac && t.force.add_jacobians != nullptr)
      out.push_back(
          "provides the add_jacobians function but declares neither PINSIM_CAP_DFDX nor "
          "PINSIM_CAP_DFDV");
    check_pairs(
        caps, {{PINSIM_CAP_ENERGY, "PINSIM_CAP_ENERGY", t.force.energy != nullptr, "energy"}}, out);
  } else if (t.kind == PINSIM_KIND_BACKEND) {
    check_pairs(
        caps,
        {{PINSIM_CAP_DISTANCE, "PINSIM_CAP_DISTANCE", t.backend.distance != nullptr, "distance"},
         {PINSIM_CAP_INPUTS, "PINSIM_CAP_INPUTS", t.backend.input != nullptr, "input"},
         {PINSIM_CAP_OUTLINES, "PINSIM_CAP_OUTLINES", t.backend.outline != nullptr, "outline"}},
        out);
  }
  std::string joined;
  for (const auto& s : out) joined += (joined.empty() ? "" : "; ") + s;
  return joined;
}

}  // namespace pinsim
