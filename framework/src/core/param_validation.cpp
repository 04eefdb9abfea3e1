#include "core/param_validation.hpp"

#include <cmath>
#include <set>
#include <sstream>

#include "core/format.hpp"
#include "core/input_error.hpp"
#include "core/value_limits.hpp"

namespace pinsim {
namespace {

std::string type_name(uint32_t t) {
  switch (t) {
    case PINSIM_PARAM_REAL:
      return "number";
    case PINSIM_PARAM_INT:
      return "integer";
    case PINSIM_PARAM_BOOL:
      return "boolean";
    case PINSIM_PARAM_STRING:
      return "string";
    case PINSIM_PARAM_VEC2:
      return "[x, y] array of two numbers";
    default:
      return "?";
  }
}

void check_range(const pinsim_param& p, double v, const std::string& at) {
  if (!std::isfinite(v)) throw SceneError(at + ": must be a finite number, got " + num(v));
  if (p.type != PINSIM_PARAM_INT && !(std::abs(v) <= kMaxParamMagnitude))
    throw SceneError(at + ": " + num(v) + " is beyond the limit of " + num(kMaxParamMagnitude) +
                     " in magnitude for a real parameter (so that energies stay finite)");
  const bool lo_x = p.flags & PINSIM_PARAM_MIN_EXCLUSIVE;
  const bool hi_x = p.flags & PINSIM_PARAM_MAX_EXCLUSIVE;
  if (lo_x ? !(v > p.min) : !(v >= p.min))
    throw SceneError(at + ": must be " + (lo_x ? "> " : ">= ") + num(p.min) + ", got " + num(v));
  if (hi_x ? !(v < p.max) : !(v <= p.max))
    throw SceneError(at + ": must be " + (hi_x ? "< " : "<= ") + num(p.max) + ", got " + num(v));
}

nlohmann::json check_value(const pinsim_param& p, const nlohmann::json& v, const std::string& at) {
  auto wrong = [&] {
    return SceneError(at + ": expected " + type_name(p.type) + ", got " +
                      std::string(v.type_name()) + " " + v.dump());
  };
  switch (p.type) {
    case PINSIM_PARAM_REAL:
      if (!v.is_number()) throw wrong();
      check_range(p, v.get<double>(), at);
      return v.get<double>();
    case PINSIM_PARAM_INT: {
      if (!v.is_number()) throw wrong();
      const double d = v.get<double>();
      if (d != std::floor(d)) throw SceneError(at + ": expected an integer, got " + v.dump());
      check_range(p, d, at);
      return static_cast<long>(d);
    }
    case PINSIM_PARAM_BOOL:
      if (!v.is_boolean()) throw wrong();
      return v;
    case PINSIM_PARAM_STRING: {
      if (!v.is_string()) throw wrong();
      if (p.choices != nullptr) {
        std::stringstream ss(p.choices);
        std::string c;
        while (std::getline(ss, c, '|'))
          if (c == v.get<std::string>()) return v;
        throw SceneError(at + ": expected one of " + std::string(p.choices) + ", got " + v.dump());
      }
      return v;
    }
    case PINSIM_PARAM_VEC2:
      if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number()) throw wrong();
      check_range(p, v[0].get<double>(), at + "[0]");
      check_range(p, v[1].get<double>(), at + "[1]");
      return nlohmann::json::array({v[0].get<double>(), v[1].get<double>()});
    default:
      throw SceneError(at + ": plugin declares an unknown parameter type " +
                       std::to_string(p.type));
  }
}

nlohmann::json default_value(const pinsim_param& p) {
  switch (p.type) {
    case PINSIM_PARAM_INT:
      return static_cast<long>(p.default_value[0]);
    case PINSIM_PARAM_BOOL:
      return p.default_value[0] != 0.0;
    case PINSIM_PARAM_STRING:
      return p.default_string ? p.default_string : "";
    case PINSIM_PARAM_VEC2:
      return nlohmann::json::array({p.default_value[0], p.default_value[1]});
    default:
      return p.default_value[0];
  }
}

}  // namespace

nlohmann::json validate_params(const pinsim_plugin& plugin, const nlohmann::json& given,
                               const std::string& where) {
  if (!given.is_null() && !given.is_object())
    throw SceneError(where + ": expected an object of parameters, got " + given.dump());
  std::set<std::string> known;
  nlohmann::json out = nlohmann::json::object();
  for (uint32_t i = 0; i < plugin.n_params; ++i) {
    const pinsim_param& p = plugin.params[i];
    known.insert(p.name);
    const std::string at = where + "." + p.name;
    if (given.is_object() && given.contains(p.name)) {
      out[p.name] = check_value(p, given.at(p.name), at);
    } else if (p.flags & PINSIM_PARAM_REQUIRED) {
      throw SceneError(at + ": required parameter of plugin '" + plugin.name + "' is missing (" +
                       type_name(p.type) + ", " + p.units + ": " + p.doc + ")");
    } else {
      out[p.name] = default_value(p);
    }
  }
  if (given.is_object()) {
    for (const auto& [key, _] : given.items()) {
      if (known.count(key)) continue;
      std::string list;
      for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
      throw SceneError(where + "." + key + ": unknown parameter of plugin '" + plugin.name +
                       "' (known: " + (list.empty() ? "none" : list) + ")");
    }
  }
  return out;
}

std::string format_param_table(const pinsim_plugin& plugin) {
  std::ostringstream o;
  o << plugin.name << " " << plugin.version << " ("
    << (plugin.kind == PINSIM_KIND_FORCE ? "force" : "backend") << ")\n  " << plugin.doc << "\n";
  if (plugin.kind == PINSIM_KIND_FORCE && plugin.arity == PINSIM_ARITY_VARIABLE)
    o << "  arity: whole bodies (each element a body or closed ring of any length)\n";
  else if (plugin.kind == PINSIM_KIND_FORCE)
    o << "  arity: " << plugin.arity << " particle(s) per element\n";
  o << "  capabilities:";
  const std::pair<uint32_t, const char*> caps[] = {
      {PINSIM_CAP_ENERGY, "energy"},
      {PINSIM_CAP_DFDX, "df/dx"},
      {PINSIM_CAP_DFDV, "df/dv"},
      {PINSIM_CAP_INTERNAL, "internal"},
      {PINSIM_CAP_DISSIPATIVE, "dissipative"},
      {PINSIM_CAP_CONCURRENT, "concurrent"},
      {PINSIM_CAP_CONSTRAINTS, "constraints"},
      {PINSIM_CAP_DPARAM, "dparam"},
      {PINSIM_CAP_JACOBIAN_PRODUCTS, "jacobian-products"},
      {PINSIM_CAP_ADJOINT_PRODUCTS, "adjoint-products"},
      {PINSIM_CAP_DISTANCE, "distance"},
      {PINSIM_CAP_PARTICLE_CONTACT, "particle-contact"},
      {PINSIM_CAP_INPUTS, "inputs"},
      {PINSIM_CAP_DIFFERENTIABLE, "differentiable"}};
  bool any = false;
  for (const auto& [bit, label] : caps)
    if (plugin.capabilities & bit) {
      o << " " << label;
      any = true;
    }
  o << (any ? "\n" : " none\n");
  o << "  parameters:\n";
  if (plugin.n_params == 0) o << "    (none)\n";
  for (uint32_t i = 0; i < plugin.n_params; ++i) {
    const pinsim_param& p = plugin.params[i];
    o << "    " << p.name << "  " << type_name(p.type) << "  default ";
    o << (p.flags & PINSIM_PARAM_REQUIRED ? std::string("(required)") : default_value(p).dump());
    std::string range;
    if (std::isfinite(p.min))
      range += std::string(p.flags & PINSIM_PARAM_MIN_EXCLUSIVE ? "> " : ">= ") + num(p.min);
    if (std::isfinite(p.max))
      range += std::string(range.empty() ? "" : ", ") +
               (p.flags & PINSIM_PARAM_MAX_EXCLUSIVE ? "< " : "<= ") + num(p.max);
    if (p.choices) range = std::string("one of ") + p.choices;
    if (!range.empty()) o << "  range " << range;
    // Units belong to quantities: a boolean or a string (a choice, a name) has none.
    const bool quantity = p.type != PINSIM_PARAM_BOOL && p.type != PINSIM_PARAM_STRING;
    if (quantity && p.units) o << "  [" << p.units << "]";
    if (p.flags & PINSIM_PARAM_DIFFERENTIABLE) o << "  differentiable";
    o << "  " << p.doc << "\n";
  }
  return o.str();
}

}  // namespace pinsim
