// plugin_table_problems: every function pointer against its capability flag, and the counts
// and strings of a table, on tables written by hand (what a plugin that bypasses the SDK, or
// sets a flag in info() by hand, exports).
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>

#include "core/plugin_table_check.hpp"

using Catch::Matchers::Contains;

namespace {

int add_force(void*, const pinsim_state_view*, double*, pinsim_error*) { return 0; }
int energy(void*, const pinsim_state_view*, double*, pinsim_error*) { return 0; }
int jacobians(void*, const pinsim_state_view*, const pinsim_triplet_sink*,
              const pinsim_triplet_sink*, pinsim_error*) {
  return 0;
}
int advance(void*, pinsim_state_mut*, double, const pinsim_event_sink*, pinsim_error*) { return 0; }
int distance(void*, const double*, double, double*, int64_t*, pinsim_error*) { return 0; }
int input(void*, const char*, int, double, pinsim_error*) { return 0; }
int constraint_set(void*, pinsim_constraint_set*, pinsim_error*) { return 0; }
int constraints(void*, const double*, const uint64_t*, uint64_t, double*, double*, pinsim_error*) {
  return 0;
}
int dforce_dparam(void*, const pinsim_state_view*, uint32_t, uint32_t, double*, pinsim_error*) {
  return 0;
}
int products(void*, const pinsim_state_view*, const double*, double*, double*, pinsim_error*) {
  return 0;
}
int adjoint_products(void*, const pinsim_state_view*, const double*, double*, double*, double*,
                     pinsim_error*) {
  return 0;
}

pinsim_plugin force_table() {
  pinsim_plugin t{};
  t.abi_version = PINSIM_ABI_VERSION;
  t.struct_size = sizeof(pinsim_plugin);
  t.abi_minor = PINSIM_ABI_MINOR;
  t.kind = PINSIM_KIND_FORCE;
  t.arity = 2;
  t.name = "spring";
  t.version = "1";
  t.doc = "";
  t.force.add_force = add_force;
  return t;
}

/// A backend's table: force_table() turned backend, with advance and no add_force.
pinsim_plugin backend_table() {
  pinsim_plugin b = force_table();
  b.kind = PINSIM_KIND_BACKEND;
  b.force.add_force = nullptr;
  b.backend.advance = advance;
  return b;
}

/// A table of `size` bytes copied from `t`, in a buffer whose bytes past it are 0xab: what a
/// reader past struct_size would see (abi_minor there reads 0xabababab).
struct ShortTable {
  alignas(pinsim_plugin) unsigned char bytes[sizeof(pinsim_plugin)];
  ShortTable(const pinsim_plugin& t, std::size_t size) {
    std::memset(bytes, 0xab, sizeof bytes);
    std::memcpy(bytes, &t, size);
    table().struct_size = static_cast<uint32_t>(size);
  }
  pinsim_plugin& table() { return *reinterpret_cast<pinsim_plugin*>(bytes); }
};

}  // namespace

TEST_CASE("table version: a table of this SDK states 4.5 and is read whole") {
  const pinsim_plugin t = force_table();
  CHECK(pinsim::table_version(t).major == PINSIM_ABI_MAJOR);
  CHECK(pinsim::table_version(t).minor == PINSIM_ABI_MINOR);
  CHECK(pinsim::table_version_problem(t).empty());
  const pinsim_plugin r = pinsim::table_as_read(t);
  CHECK(std::memcmp(&r, &t, sizeof r) == 0);
}

TEST_CASE("table version: a 4.0 table has no abi_minor, and nothing past it is read") {
  ShortTable s(force_table(), PINSIM_ABI_MIN_TABLE_SIZE);
  const pinsim_plugin& t = s.table();
  CHECK_FALSE(PINSIM_TABLE_HAS(&t, abi_minor));
  CHECK(pinsim::table_version(t).minor == 0);  // not 0xabababab
  CHECK(pinsim::table_version_problem(t).empty());
  const pinsim_plugin r = pinsim::table_as_read(t);
  CHECK(r.abi_minor == 0);
  CHECK(r.struct_size == PINSIM_ABI_MIN_TABLE_SIZE);
  CHECK(std::memcmp(&r, &t, PINSIM_ABI_MIN_TABLE_SIZE) == 0);
  CHECK(pinsim::plugin_table_problems(r).empty());
  // a table that ends inside abi_minor does not hold it either
  ShortTable half(force_table(), PINSIM_ABI_MIN_TABLE_SIZE + 2);
  CHECK(pinsim::table_version(half.table()).minor == 0);
  CHECK(pinsim::table_as_read(half.table()).abi_minor == 0);
}

TEST_CASE("table version: another major, a short table, a newer or a missing minor") {
  pinsim_plugin t = force_table();
  t.abi_version = PINSIM_ABI_MAJOR + 1;
  CHECK_THAT(pinsim::table_version_problem(t),
             Contains("wrong plugin ABI version: plugin has 5, this pinsim expects 4") &&
                 Contains("this pinsim has ABI 4.5 and loads plugins of ABI 4.0 to 4.5") &&
                 Contains("built for a newer pinsim"));
  t.abi_version = PINSIM_ABI_MAJOR - 1;
  CHECK_THAT(pinsim::table_version_problem(t), Contains("plugin has 3, this pinsim expects 4") &&
                                                   Contains("rebuild it against this SDK"));
  ShortTable s(force_table(), PINSIM_ABI_MIN_TABLE_SIZE - 8);
  CHECK_THAT(pinsim::table_version_problem(s.table()),
             Contains("wrong plugin table size: plugin has ABI 4 and a table of " +
                      std::to_string(PINSIM_ABI_MIN_TABLE_SIZE - 8) + " bytes"));
  t = force_table();
  t.abi_minor = PINSIM_ABI_MINOR + 1;
  CHECK_THAT(pinsim::table_version_problem(t),
             Contains("plugin built against ABI 4.6, newer than this pinsim's 4.5"));
  t.abi_minor = 0;  // holds abi_minor, but says 4.0
  CHECK_THAT(pinsim::table_version_problem(t),
             Contains("malformed plugin table: it holds abi_minor") && Contains("states minor 0"));
}

TEST_CASE("table check: consistent force and backend tables pass") {
  pinsim_plugin t = force_table();
  CHECK(pinsim::plugin_table_problems(t).empty());
  t.capabilities = PINSIM_CAP_ENERGY | PINSIM_CAP_DFDX | PINSIM_CAP_INTERNAL;
  t.force.energy = energy;
  t.force.add_jacobians = jacobians;
  CHECK(pinsim::plugin_table_problems(t).empty());
  pinsim_plugin b = backend_table();
  b.capabilities = PINSIM_CAP_DISTANCE | PINSIM_CAP_PARTICLE_CONTACT;
  b.backend.distance = distance;
  CHECK(pinsim::plugin_table_problems(b).empty());
}

TEST_CASE("table check: a flag without its function, or a function without its flag") {
  pinsim_plugin t = force_table();
  t.capabilities = PINSIM_CAP_ENERGY;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("declares PINSIM_CAP_ENERGY but its energy function is NULL"));
  t.capabilities = PINSIM_CAP_DFDV;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("declares PINSIM_CAP_DFDV but its add_jacobians function is NULL"));
  t.capabilities = 0;
  t.force.energy = energy;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("provides the energy function but does not declare PINSIM_CAP_ENERGY"));
  t.force.energy = nullptr;
  t.force.add_jacobians = jacobians;
  CHECK_THAT(pinsim::plugin_table_problems(t), Contains("declares neither PINSIM_CAP_DFDX"));
  pinsim_plugin b = force_table();
  b.kind = PINSIM_KIND_BACKEND;
  b.backend.advance = advance;
  b.capabilities = PINSIM_CAP_INPUTS | PINSIM_CAP_OUTLINES;
  b.backend.input = input;
  const std::string bad = pinsim::plugin_table_problems(b);
  CHECK_THAT(bad, Contains("declares PINSIM_CAP_OUTLINES but its outline function is NULL"));
  CHECK(bad.find("INPUTS") == std::string::npos);
}

TEST_CASE("table check: the 4.2 constraint entries go with PINSIM_CAP_CONSTRAINTS") {
  pinsim_plugin t = force_table();
  t.capabilities = PINSIM_CAP_CONSTRAINTS;
  t.constraint_set = constraint_set;
  t.constraints = constraints;
  CHECK(pinsim::plugin_table_problems(t).empty());
  t.constraints = nullptr;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("declares PINSIM_CAP_CONSTRAINTS but its constraints function is NULL"));
  t.capabilities = 0;
  t.constraints = constraints;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("provides the constraint_set function but does not declare "
                      "PINSIM_CAP_CONSTRAINTS"));
  // a 4.1 table is read without them, whatever lies past its end
  pinsim_plugin full = force_table();
  full.constraint_set = constraint_set;
  full.constraints = constraints;
  full.capabilities = PINSIM_CAP_CONSTRAINTS;
  ShortTable old(full, offsetof(pinsim_plugin, abi_minor) + sizeof(uint32_t));
  old.table().abi_minor = 1;
  CHECK(pinsim::table_version_problem(old.table()).empty());
  const pinsim_plugin r = pinsim::table_as_read(old.table());
  CHECK(r.constraint_set == nullptr);
  CHECK(r.constraints == nullptr);
  // and a backend never has them
  pinsim_plugin b = backend_table();
  b.constraint_set = constraint_set;
  CHECK_THAT(pinsim::plugin_table_problems(b),
             Contains("is a backend but provides the constraint"));
}

TEST_CASE("table check: counts, strings and parameters") {
  pinsim_plugin t = force_table();
  t.version = nullptr;
  t.n_params = 3;
  CHECK_THAT(pinsim::plugin_table_problems(t), Contains("its version string is NULL"));
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("declares 3 parameters but its params array is NULL"));
  t = force_table();
  t.n_params = 1u << 30;
  CHECK_THAT(pinsim::plugin_table_problems(t), Contains("declares 1073741824 parameters"));
  pinsim_param p[3] = {};
  p[0] = {"k", PINSIM_PARAM_REAL, 0, {1, 0}, nullptr, nullptr, 0, HUGE_VAL, "N/m", "stiffness"};
  p[1] = p[0];                                                                // the same name twice
  p[2] = {nullptr, 99, 0, {0, 0}, nullptr, nullptr, 0, 0, nullptr, nullptr};  // nameless
  t = force_table();
  t.params = p;
  t.n_params = 3;
  const std::string bad = pinsim::plugin_table_problems(t);
  CHECK_THAT(bad, Contains("parameter 1 'k' is declared twice"));
  CHECK_THAT(bad, Contains("parameter 2 has no name"));
  p[2] = {"c", 99, 0, {0, 0}, nullptr, nullptr, 0, 0, nullptr, "x"};
  const std::string bad2 = pinsim::plugin_table_problems(t);
  CHECK_THAT(bad2, Contains("parameter 2 'c' has an unknown type 99"));
  CHECK_THAT(bad2, Contains("parameter 2 'c' has NULL units"));
  t = force_table();
  t.arity = 1u << 20;
  CHECK_THAT(pinsim::plugin_table_problems(t), Contains("declares arity 1048576"));
}

TEST_CASE("table check: the 4.4 add_dforce_dparam goes with PINSIM_CAP_DPARAM and its flags") {
  pinsim_param p[2] = {};
  p[0] = {
      "k",   PINSIM_PARAM_REAL, PINSIM_PARAM_DIFFERENTIABLE, {1, 0}, nullptr, nullptr, 0, HUGE_VAL,
      "N/m", "stiffness"};
  p[1] = {"mode", PINSIM_PARAM_STRING, 0, {0, 0}, "a", "a|b", 0, 0, "1", "mode"};
  pinsim_plugin t = force_table();
  t.params = p;
  t.n_params = 2;
  t.capabilities = PINSIM_CAP_DPARAM;
  t.add_dforce_dparam = dforce_dparam;
  CHECK(pinsim::plugin_table_problems(t).empty());
  // the entry without its flag, the flag without its entry
  t.capabilities = 0;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("provides the add_dforce_dparam function but does not declare "
                      "PINSIM_CAP_DPARAM"));
  t.capabilities = PINSIM_CAP_DPARAM;
  t.add_dforce_dparam = nullptr;
  const std::string missing = pinsim::plugin_table_problems(t);
  CHECK_THAT(missing, Contains("declares PINSIM_CAP_DPARAM but its add_dforce_dparam function "
                               "is NULL"));
  CHECK_THAT(missing, Contains("parameter 0 'k' is flagged PINSIM_PARAM_DIFFERENTIABLE but the "
                               "plugin has no add_dforce_dparam function"));
  // a string parameter cannot be differentiated; an entry with no flagged parameter is idle
  t.add_dforce_dparam = dforce_dparam;
  p[1].flags = PINSIM_PARAM_DIFFERENTIABLE;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("parameter 1 'mode' is flagged PINSIM_PARAM_DIFFERENTIABLE but is not a "
                      "REAL or VEC2 parameter"));
  p[0].flags = p[1].flags = 0;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("provides the add_dforce_dparam function but flags no parameter"));
  // a 4.3 table is read without it, whatever lies past its end
  p[0].flags = PINSIM_PARAM_DIFFERENTIABLE;
  ShortTable old(t, offsetof(pinsim_plugin, record_drift) + sizeof(void*));
  old.table().abi_minor = 3;
  old.table().capabilities = 0;  // bit 7 meant nothing before 4.4
  CHECK(pinsim::table_version_problem(old.table()).empty());
  old.table().add_jacobian_products = products;
  CHECK(pinsim::table_as_read(old.table()).add_dforce_dparam == nullptr);
  CHECK(pinsim::table_as_read(old.table()).add_jacobian_products == nullptr);
  CHECK(pinsim::plugin_table_problems(pinsim::table_as_read(old.table())).empty());
  // a table stating 4.4 must hold it
  ShortTable cut(t, offsetof(pinsim_plugin, record_drift) + sizeof(void*));
  cut.table().abi_minor = 4;
  CHECK_THAT(pinsim::table_version_problem(cut.table()),
             Contains("wrong plugin table size: plugin has ABI 4.4"));
  // and a backend never has it
  pinsim_plugin b = backend_table();
  b.add_dforce_dparam = dforce_dparam;
  CHECK_THAT(pinsim::plugin_table_problems(b),
             Contains("is a backend but provides the add_dforce_dparam, add_jacobian_products"));
}

TEST_CASE("table check: the 4.4 add_jacobian_products goes with its flag and the Jacobians") {
  pinsim_plugin t = force_table();
  t.capabilities = PINSIM_CAP_DFDX | PINSIM_CAP_JACOBIAN_PRODUCTS;
  t.force.add_jacobians = jacobians;
  t.add_jacobian_products = products;
  CHECK(pinsim::plugin_table_problems(t).empty());
  t.capabilities = PINSIM_CAP_DFDX;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("provides the add_jacobian_products function but does not declare "
                      "PINSIM_CAP_JACOBIAN_PRODUCTS"));
  t.capabilities = PINSIM_CAP_JACOBIAN_PRODUCTS;
  t.force.add_jacobians = nullptr;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("provides the add_jacobian_products function but does not declare "
                      "PINSIM_CAP_DFDX"));
  t.capabilities = PINSIM_CAP_DFDX | PINSIM_CAP_JACOBIAN_PRODUCTS;
  t.force.add_jacobians = jacobians;
  t.add_jacobian_products = nullptr;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("declares PINSIM_CAP_JACOBIAN_PRODUCTS but its add_jacobian_products "
                      "function is NULL"));
}

TEST_CASE("table check: the 4.5 add_adjoint_products goes with its flag and the two it fuses") {
  pinsim_param p = {
      "k",   PINSIM_PARAM_REAL, PINSIM_PARAM_DIFFERENTIABLE, {1, 0}, nullptr, nullptr, 0, HUGE_VAL,
      "N/m", "stiffness"};
  pinsim_plugin t = force_table();
  t.params = &p;
  t.n_params = 1;
  t.capabilities = PINSIM_CAP_DFDX | PINSIM_CAP_JACOBIAN_PRODUCTS | PINSIM_CAP_DPARAM |
                   PINSIM_CAP_ADJOINT_PRODUCTS;
  t.force.add_jacobians = jacobians;
  t.add_jacobian_products = products;
  t.add_dforce_dparam = dforce_dparam;
  t.add_adjoint_products = adjoint_products;
  CHECK(pinsim::plugin_table_problems(t).empty());
  t.capabilities &= ~static_cast<uint32_t>(PINSIM_CAP_ADJOINT_PRODUCTS);
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("provides the add_adjoint_products function but does not declare "
                      "PINSIM_CAP_ADJOINT_PRODUCTS"));
  t.capabilities |= PINSIM_CAP_ADJOINT_PRODUCTS;
  t.add_adjoint_products = nullptr;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("declares PINSIM_CAP_ADJOINT_PRODUCTS but its add_adjoint_products "
                      "function is NULL"));
  // it fuses the products and the parameter derivatives: it needs both entries
  t.add_adjoint_products = adjoint_products;
  t.capabilities &= ~static_cast<uint32_t>(PINSIM_CAP_JACOBIAN_PRODUCTS);
  t.add_jacobian_products = nullptr;
  CHECK_THAT(pinsim::plugin_table_problems(t),
             Contains("provides the add_adjoint_products function without add_jacobian_products "
                      "and add_dforce_dparam"));
  // a 4.4 table is read without it, whatever lies past its end
  t.capabilities |= PINSIM_CAP_JACOBIAN_PRODUCTS;
  t.add_jacobian_products = products;
  ShortTable old(t, offsetof(pinsim_plugin, add_jacobian_products) + sizeof(void*));
  old.table().abi_minor = 4;
  old.table().capabilities &= ~static_cast<uint32_t>(PINSIM_CAP_ADJOINT_PRODUCTS);
  CHECK(pinsim::table_version_problem(old.table()).empty());
  const pinsim_plugin r = pinsim::table_as_read(old.table());
  CHECK(r.add_adjoint_products == nullptr);
  CHECK(r.add_jacobian_products == products);
  CHECK(pinsim::plugin_table_problems(r).empty());
  // a table stating 4.5 must hold it
  ShortTable cut(t, offsetof(pinsim_plugin, add_jacobian_products) + sizeof(void*));
  CHECK_THAT(pinsim::table_version_problem(cut.table()),
             Contains("wrong plugin table size: plugin has ABI 4.5"));
  // and a backend never has it
  pinsim_plugin b = backend_table();
  b.add_adjoint_products = adjoint_products;
  CHECK_THAT(pinsim::plugin_table_problems(b),
             Contains("add_adjoint_products function of a force"));
}
