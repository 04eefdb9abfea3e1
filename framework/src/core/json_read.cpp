#include "core/json_read.hpp"

#include <cmath>

namespace pinsim {

std::string describe(const nlohmann::json& v) {
  std::string s = v.dump();
  if (s.size() > 60) s = s.substr(0, 57) + "...";
  return std::string("got ") + v.type_name() + " " + s;
}

void require_object(const nlohmann::json& j, const Loc& at) {
  if (!j.is_object()) throw at.error("expected an object, " + describe(j));
}

void check_keys(const nlohmann::json& obj, std::initializer_list<const char*> allowed,
                const Loc& at) {
  for (const auto& [key, _] : obj.items()) {
    bool ok = false;
    for (const char* a : allowed) ok = ok || key == a;
    if (ok) continue;
    std::string list;
    for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    throw(at / key).error("unknown key (expected one of: " + list + ")");
  }
}

static double as_number(const nlohmann::json& v, const Loc& at) {
  if (!v.is_number()) throw at.error("expected a number, " + describe(v));
  const double d = v.get<double>();
  if (!std::isfinite(d)) throw at.error("expected a finite number");
  return d;
}

double read_number(const nlohmann::json& obj, const char* key, const Loc& at) {
  if (!obj.contains(key)) throw(at / key).error("required number is missing");
  return as_number(obj.at(key), at / key);
}

double read_number_or(const nlohmann::json& obj, const char* key, double def, const Loc& at) {
  return obj.contains(key) ? as_number(obj.at(key), at / key) : def;
}

Eigen::Vector2d read_vec2(const nlohmann::json& v, const Loc& at) {
  if (!v.is_array() || v.size() != 2) throw at.error("expected [x, y], " + describe(v));
  return {as_number(v[0], at[0]), as_number(v[1], at[1])};
}

Eigen::Vector2d read_vec2_or(const nlohmann::json& obj, const char* key, const Eigen::Vector2d& def,
                             const Loc& at) {
  return obj.contains(key) ? read_vec2(obj.at(key), at / key) : def;
}

std::string read_string_or(const nlohmann::json& obj, const char* key, const std::string& def,
                           const Loc& at) {
  if (!obj.contains(key)) return def;
  const auto& v = obj.at(key);
  if (!v.is_string()) throw(at / key).error("expected a string, " + describe(v));
  return v.get<std::string>();
}

bool read_bool_or(const nlohmann::json& obj, const char* key, bool def, const Loc& at) {
  if (!obj.contains(key)) return def;
  const auto& v = obj.at(key);
  if (!v.is_boolean()) throw(at / key).error("expected true or false, " + describe(v));
  return v.get<bool>();
}

uint64_t read_count_or(const nlohmann::json& obj, const char* key, uint64_t def, const Loc& at) {
  if (!obj.contains(key)) return def;
  const auto& v = obj.at(key);
  if (!v.is_number_integer() || v.get<long long>() < 0)
    throw(at / key).error("expected a non-negative integer, " + describe(v));
  return v.get<uint64_t>();
}

nlohmann::json parse_json_text(const std::string& text, const std::string& label) {
  try {
    return nlohmann::json::parse(text, nullptr, true, /*ignore_comments=*/true);
  } catch (const nlohmann::json::parse_error& e) {
    // Turn the byte offset into line:column.
    std::size_t line = 1, col = 1;
    for (std::size_t i = 0; i + 1 < e.byte && i < text.size(); ++i) {
      if (text[i] == '\n') {
        ++line;
        col = 1;
      } else {
        ++col;
      }
    }
    std::string what = e.what();
    if (auto p = what.find("syntax error"); p != std::string::npos) what = what.substr(p);
    throw SceneError(label + ":" + std::to_string(line) + ":" + std::to_string(col) +
                     ": malformed JSON: " + what);
  }
}

}  // namespace pinsim
