// `pinsim check-plugin`: the list of checks in the order they run, the floating-point traps
// around them, and the report as a table and as JSON.
#include "tools/plugin_check.hpp"

#include <fenv.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <sstream>

#include "core/format.hpp"
#include "core/plugin_table_check.hpp"
#include "tools/plugin_checker.hpp"

namespace pinsim {
namespace plugin_check {

CheckReport Checker::run() {
  CheckReport rep;
  rep.plugin = t_->name;
  rep.path = plugin_.path.string();
  rep.layout = layout_.description;
  // Creation first: if the plugin cannot even be instantiated, the rest is moot.
  CheckResult create{
      "create", "instances build from random states and element lists", CheckStatus::Pass, 0.0, 0.0,
      ""};
  try {
    make(rest_state());
    create.detail = layout_.description;
  } catch (const std::exception& e) {
    create.status = CheckStatus::Fail;
    create.detail = e.what();
    rep.checks.push_back(create);
    return rep;
  }
  rep.checks.push_back(create);
  using Fn = std::function<CheckResult()>;
  const std::vector<std::pair<std::string, Fn>> checks = {
      {"gradient", [&] { return gradient_check(); }},
      {"dfdx", [&] { return jacobian_check(0); }},
      {"dfdv", [&] { return jacobian_check(1); }},
      {"momentum", [&] { return momentum_check(false); }},
      {"angular_momentum", [&] { return momentum_check(true); }},
      {"rigid_invariance", [&] { return invariance_check(); }},
      {"degenerate", [&] { return degenerate_check(); }},
      {"dissipation", [&] { return dissipation_check(); }},
      {"constraint_energy", [&] { return constraint_check(0); }},
      {"constraint_force", [&] { return constraint_check(1); }},
      {"constraint_gradient", [&] { return constraint_check(2); }},
      {"dparam", [&] { return dparam_check(); }},
      {"jacobian_products", [&] { return products_check(); }},
      {"adjoint_products", [&] { return adjoint_products_check(); }},
  };
  for (const auto& [name, fn] : checks) {
    if (!opt_.only.empty() && name != opt_.only) continue;
    // The constraint checks are listed only for a plugin that has constraints (or when asked
    // for by name): a plugin without them is not one check short.
    if (opt_.only.empty() && name.rfind("constraint_", 0) == 0 &&
        !(t_->capabilities & PINSIM_CAP_CONSTRAINTS))
      continue;
    // likewise the parameter derivatives (ABI 4.4)
    if (opt_.only.empty() && name == "dparam" && !(t_->capabilities & PINSIM_CAP_DPARAM)) continue;
    if (opt_.only.empty() && name == "jacobian_products" &&
        !(t_->capabilities & PINSIM_CAP_JACOBIAN_PRODUCTS))
      continue;
    if (opt_.only.empty() && name == "adjoint_products" &&
        !(t_->capabilities & PINSIM_CAP_ADJOINT_PRODUCTS))
      continue;
    try {
      rep.checks.push_back(fn());
    } catch (const std::exception& e) {
      CheckResult r{name, "",      CheckStatus::Fail, std::numeric_limits<double>::infinity(),
                    0.0,  e.what()};
      rep.checks.push_back(r);
    }
  }
  return rep;
}

}  // namespace plugin_check

namespace {

/// Floating-point traps off for the engine's lifetime, restored after.
class TrapsOff {
 public:
  TrapsOff() : saved_(fegetexcept()) { fedisableexcept(FE_ALL_EXCEPT); }
  ~TrapsOff() {
    feclearexcept(FE_ALL_EXCEPT);
    feenableexcept(saved_);
  }
  TrapsOff(const TrapsOff&) = delete;
  TrapsOff& operator=(const TrapsOff&) = delete;

 private:
  int saved_;
};

const char* status_name(CheckStatus s) {
  switch (s) {
    case CheckStatus::Pass:
      return "pass";
    case CheckStatus::Fail:
      return "FAIL";
    case CheckStatus::Skip:
      return "skip";
  }
  return "?";
}

}  // namespace

bool CheckReport::passed() const {
  return std::none_of(checks.begin(), checks.end(),
                      [](const CheckResult& c) { return c.status == CheckStatus::Fail; });
}

const CheckResult* CheckReport::find(const std::string& name) const {
  for (const auto& c : checks)
    if (c.name == name) return &c;
  return nullptr;
}

CheckReport check_force_plugin(const LoadedPlugin& plugin, const CheckOptions& opt) {
  if (!plugin.is_force())
    throw LoadError(plugin.path.string() + ": '" + plugin.name() +
                    "' is not a force plugin; check-plugin checks force plugins");
  if (opt.scene != nullptr && opt.force_index >= opt.scene->forces.size())
    throw InputError(opt.scene->label + ": --force-index " + std::to_string(opt.force_index) +
                     ": the scene has " + std::to_string(opt.scene->forces.size()) + " force(s)");
  // A table whose flags promise a function it lacks would be called through NULL: its
  // own failure, before anything is called (tables loaded from a file were checked already).
  if (const std::string bad = plugin_table_problems(*plugin.table); !bad.empty()) {
    CheckReport rep;
    rep.plugin = plugin.name();
    rep.path = plugin.path.string();
    rep.checks.push_back({"table", "function pointers match the capability flags",
                          CheckStatus::Fail, std::numeric_limits<double>::infinity(), 0.0, bad});
    return rep;
  }
  TrapsOff traps;
  plugin_check::Checker c(plugin, opt);
  return c.run();
}

std::string format_report(const CheckReport& rep) {
  std::ostringstream o;
  o << "check-plugin " << rep.plugin << " (" << rep.path << ")\n";
  if (!rep.layout.empty()) o << "  on " << rep.layout << "\n";
  for (const auto& c : rep.checks) {
    char line[160];
    std::snprintf(line, sizeof line, "  %-4s  %-17s worst %-9s tol %-8s ", status_name(c.status),
                  c.name.c_str(), c.status == CheckStatus::Skip ? "-" : num(c.worst, 3).c_str(),
                  c.tolerance > 0 ? num(c.tolerance, 3).c_str() : "-");
    o << line << c.detail << "\n";
  }
  int passes = 0, fails = 0;
  std::string skipped;
  for (const auto& c : rep.checks) {
    passes += c.status == CheckStatus::Pass ? 1 : 0;
    fails += c.status == CheckStatus::Fail ? 1 : 0;
    if (c.status == CheckStatus::Skip) skipped += (skipped.empty() ? "" : ", ") + c.name;
  }
  const std::size_t skips = rep.checks.size() - static_cast<std::size_t>(passes + fails);
  o << (fails == 0 ? "PASS" : "FAIL") << ": " << rep.plugin << ", " << rep.checks.size()
    << " checks: " << passes << " passed, " << fails << " failed, " << skips << " skipped"
    << (skips > 0 ? " (" + skipped + ")" : std::string()) << "\n";
  return o.str();
}

nlohmann::json report_json(const CheckReport& rep) {
  nlohmann::json j;
  j["plugin"] = rep.plugin;
  j["path"] = rep.path;
  j["layout"] = rep.layout;
  j["passed"] = rep.passed();
  j["checks"] = nlohmann::json::array();
  for (const auto& c : rep.checks) {
    nlohmann::json cj;
    cj["name"] = c.name;
    cj["what"] = c.what;
    cj["status"] = c.status == CheckStatus::Pass   ? "pass"
                   : c.status == CheckStatus::Fail ? "fail"
                                                   : "skip";
    cj["worst"] = std::isfinite(c.worst) ? nlohmann::json(c.worst) : nlohmann::json("inf");
    cj["tolerance"] = c.tolerance;
    cj["detail"] = c.detail;
    j["checks"].push_back(cj);
  }
  return j;
}

}  // namespace pinsim
