#include "core/plugin_table_check.hpp"

#include <cstddef>
#include <cstring>
#include <iterator>
#include <set>
#include <string_view>
#include <vector>

namespace pinsim {
namespace {

/// Where the table of each minor of this major ends (index: the minor): a table stating
/// minor m is at least this long. A new minor appends the end of its last entry.
constexpr std::size_t kMinorTableEnd[] = {
    PINSIM_ABI_MIN_TABLE_SIZE,                              // 4.0: up to `backend`
    offsetof(pinsim_plugin, abi_minor) + sizeof(uint32_t),  // 4.1: abi_minor
    offsetof(pinsim_plugin, constraints) + sizeof(void*),   // 4.2: constraint_set, constraints
    offsetof(pinsim_plugin, record_drift) + sizeof(void*),  // 4.3: record_drift
    offsetof(pinsim_plugin, add_jacobian_products) + sizeof(void*),  // 4.4: add_dforce_dparam,
                                                                     // add_jacobian_products
    offsetof(pinsim_plugin, add_adjoint_products) + sizeof(void*),   // 4.5: add_adjoint_products
};
static_assert(std::size(kMinorTableEnd) == PINSIM_ABI_MINOR + 1, "one table end per minor");

std::string version_text(uint32_t major, uint32_t minor) {
  return std::to_string(major) + "." + std::to_string(minor);
}

/// This pinsim's version and the range of plugins it loads, for messages.
std::string host_versions() {
  return "this pinsim has ABI " + version_text(PINSIM_ABI_MAJOR, PINSIM_ABI_MINOR) +
         " and loads plugins of ABI " + version_text(PINSIM_ABI_MAJOR, 0) + " to " +
         version_text(PINSIM_ABI_MAJOR, PINSIM_ABI_MINOR);
}

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

/// A force's parameters flagged PINSIM_PARAM_DIFFERENTIABLE: only REAL or VEC2 ones, and
/// with add_dforce_dparam (which, in turn, must have at least one). A table of a minor before
/// 4.4 knows nothing of the flag: its bit is not read there.
void check_differentiable_params(const pinsim_plugin& t, std::vector<std::string>& out) {
  if (t.n_params > kMaxPluginParams || (t.n_params > 0 && t.params == nullptr)) return;
  if (table_version(t).minor < 4) return;
  uint32_t flagged = 0;
  for (uint32_t i = 0; i < t.n_params; ++i) {
    const pinsim_param& p = t.params[i];
    if (!(p.flags & PINSIM_PARAM_DIFFERENTIABLE)) continue;
    ++flagged;
    const std::string named =
        "parameter " + std::to_string(i) + " '" + (p.name != nullptr ? p.name : "") + "'";
    if (p.type != PINSIM_PARAM_REAL && p.type != PINSIM_PARAM_VEC2)
      out.push_back(named +
                    " is flagged PINSIM_PARAM_DIFFERENTIABLE but is not a REAL or VEC2 parameter");
    if (t.add_dforce_dparam == nullptr)
      out.push_back(named +
                    " is flagged PINSIM_PARAM_DIFFERENTIABLE but the plugin has no "
                    "add_dforce_dparam function");
  }
  if (t.add_dforce_dparam != nullptr && flagged == 0)
    out.push_back(
        "provides the add_dforce_dparam function but flags no parameter "
        "PINSIM_PARAM_DIFFERENTIABLE");
}

}  // namespace

TableVersion table_version(const pinsim_plugin& t) {
  TableVersion v;
  v.major = t.abi_version;
  if (PINSIM_TABLE_HAS(&t, abi_minor)) v.minor = t.abi_minor;
  return v;
}

std::string table_version_problem(const pinsim_plugin& t) {
  // abi_version and struct_size are in every table; nothing else is read before they pass.
  if (t.abi_version != PINSIM_ABI_MAJOR) {
    const bool newer = t.abi_version > PINSIM_ABI_MAJOR;
    return "wrong plugin ABI version: plugin has " + std::to_string(t.abi_version) +
           ", this pinsim expects " + std::to_string(PINSIM_ABI_MAJOR) + " (" + host_versions() +
           "): " +
           (newer ? "the plugin was built for a newer pinsim; run it with that one, or rebuild "
                    "it against this SDK"
                  : "rebuild it against this SDK");
  }
  if (t.struct_size < PINSIM_ABI_MIN_TABLE_SIZE)
    return "wrong plugin table size: plugin has ABI " + std::to_string(t.abi_version) +
           " and a table of " + std::to_string(t.struct_size) + " bytes, shorter than the " +
           std::to_string(PINSIM_ABI_MIN_TABLE_SIZE) +
           " bytes of the smallest table of its major (" + version_text(PINSIM_ABI_MAJOR, 0) +
           "); " + host_versions() + ": rebuild it against this SDK";
  const TableVersion v = table_version(t);
  const std::string plugin = version_text(v.major, v.minor);
  if (v.minor > PINSIM_ABI_MINOR)
    return "plugin built against ABI " + plugin + ", newer than this pinsim's " +
           version_text(PINSIM_ABI_MAJOR, PINSIM_ABI_MINOR) +
           " (it may read what this pinsim does not provide): run it with a pinsim of ABI " +
           plugin + " or later, or rebuild it against this SDK";
  if (v.minor == 0 && PINSIM_TABLE_HAS(&t, abi_minor))
    return "malformed plugin table: it holds abi_minor, an entry of ABI " +
           version_text(PINSIM_ABI_MAJOR, 1) + " and later, but states minor 0; " + host_versions();
  if (t.struct_size < kMinorTableEnd[v.minor])
    return "wrong plugin table size: plugin has ABI " + plugin + " and a table of " +
           std::to_string(t.struct_size) + " bytes, shorter than the " +
           std::to_string(kMinorTableEnd[v.minor]) + " bytes of every " + plugin + " table; " +
           host_versions() + ": rebuild it against this SDK";
  return "";
}

pinsim_plugin table_as_read(const pinsim_plugin& t) {
  // Entry by entry: the 4.0 table whole, then each later entry only if the table holds it.
  pinsim_plugin out{};
  std::memcpy(&out, &t, PINSIM_ABI_MIN_TABLE_SIZE);
  const TableVersion v = table_version(t);
  out.abi_minor = v.minor;
  if (v.minor >= 2 && PINSIM_TABLE_HAS(&t, constraints)) {
    out.constraint_set = t.constraint_set;
    out.constraints = t.constraints;
  }
  if (v.minor >= 3 && PINSIM_TABLE_HAS(&t, record_drift)) out.record_drift = t.record_drift;
  if (v.minor >= 4 && PINSIM_TABLE_HAS(&t, add_jacobian_products)) {
    out.add_dforce_dparam = t.add_dforce_dparam;
    out.add_jacobian_products = t.add_jacobian_products;
  }
  if (v.minor >= 5 && PINSIM_TABLE_HAS(&t, add_adjoint_products))
    out.add_adjoint_products = t.add_adjoint_products;
  return out;
}

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
    check_pairs(caps,
                {{PINSIM_CAP_ENERGY, "PINSIM_CAP_ENERGY", t.force.energy != nullptr, "energy"},
                 {PINSIM_CAP_CONSTRAINTS, "PINSIM_CAP_CONSTRAINTS", t.constraint_set != nullptr,
                  "constraint_set"},
                 {PINSIM_CAP_CONSTRAINTS, "PINSIM_CAP_CONSTRAINTS", t.constraints != nullptr,
                  "constraints"},
                 {PINSIM_CAP_DPARAM, "PINSIM_CAP_DPARAM", t.add_dforce_dparam != nullptr,
                  "add_dforce_dparam"},
                 {PINSIM_CAP_JACOBIAN_PRODUCTS, "PINSIM_CAP_JACOBIAN_PRODUCTS",
                  t.add_jacobian_products != nullptr, "add_jacobian_products"},
                 {PINSIM_CAP_ADJOINT_PRODUCTS, "PINSIM_CAP_ADJOINT_PRODUCTS",
                  t.add_adjoint_products != nullptr, "add_adjoint_products"}},
                out);
    if (t.add_adjoint_products != nullptr &&
        (t.add_jacobian_products == nullptr || t.add_dforce_dparam == nullptr))
      out.push_back(
          "provides the add_adjoint_products function without add_jacobian_products and "
          "add_dforce_dparam (it fuses those two)");
    if (t.add_jacobian_products != nullptr && !(caps & PINSIM_CAP_DFDX))
      out.push_back(
          "provides the add_jacobian_products function but does not declare "
          "PINSIM_CAP_DFDX (the products are of the Jacobians it gives)");
    check_differentiable_params(t, out);
  } else if (t.kind == PINSIM_KIND_BACKEND) {
    check_pairs(
        caps,
        {{PINSIM_CAP_DISTANCE, "PINSIM_CAP_DISTANCE", t.backend.distance != nullptr, "distance"},
         {PINSIM_CAP_INPUTS, "PINSIM_CAP_INPUTS", t.backend.input != nullptr, "input"},
         {PINSIM_CAP_OUTLINES, "PINSIM_CAP_OUTLINES", t.backend.outline != nullptr, "outline"}},
        out);
    if (t.constraint_set != nullptr || t.constraints != nullptr)
      out.push_back("is a backend but provides the constraint functions of a force");
    if (t.add_dforce_dparam != nullptr || t.add_jacobian_products != nullptr ||
        t.add_adjoint_products != nullptr)
      out.push_back(
          "is a backend but provides the add_dforce_dparam, add_jacobian_products or "
          "add_adjoint_products function of a force");
    if (t.record_drift != nullptr && !(caps & PINSIM_CAP_DIFFERENTIABLE))
      out.push_back(
          "provides the record_drift function but does not declare "
          "PINSIM_CAP_DIFFERENTIABLE");
  }
  if (t.kind == PINSIM_KIND_FORCE && t.record_drift != nullptr)
    out.push_back("is a force but provides the record_drift function of a backend");
  std::string joined;
  for (const auto& s : out) joined += (joined.empty() ? "" : "; ") + s;
  return joined;
}

}  // namespace pinsim
