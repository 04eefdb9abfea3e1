// JsonIn: reads one JSON object of the scene with its path, for errors such as
// "pinball.json: obstacles[3].shape.radius: must be > 0, got -1".
#pragma once

#include <initializer_list>
#include <pinsim/plugin.hpp>
#include <string>

namespace pinsim::sdf {

class JsonIn {
 public:
  /// `ctx` is the scene file name, `path` the JSON path of `j` (e.g. "obstacles[3].shape").
  JsonIn(const nlohmann::json& j, std::string path, std::string ctx)
      : j_(j), path_(std::move(path)), ctx_(std::move(ctx)) {}

  const nlohmann::json& json() const { return j_; }
  const std::string& path() const { return path_; }
  const std::string& ctx() const { return ctx_; }

  /// Path of a key below this object.
  std::string at(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  /// Throws "ctx: path.key: what".
  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw Error(ctx_ + ": " + (key.empty() ? path_ : at(key)) + ": " + what);
  }
  /// A short rendering of a value for "got ..." messages.
  static std::string show(const nlohmann::json& v) {
    std::string s = v.dump();
    return s.size() > 60 ? s.substr(0, 57) + "..." : s;
  }

  /// Requires an object whose keys are all in `allowed`.
  void only(std::initializer_list<const char*> allowed) const {
    if (!j_.is_object()) fail("", "expected an object, got " + show(j_));
    for (const auto& [k, v] : j_.items()) {
      bool ok = false;
      for (const char* a : allowed) ok = ok || k == a;
      if (!ok) {
        std::string list;
        for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
        fail(k, "unknown key (expected one of: " + list + ")");
      }
    }
  }
  bool has(const char* key) const { return j_.contains(key) && !j_.at(key).is_null(); }

  double number(const char* key) const {
    if (!has(key)) fail(key, "required number is missing");
    const auto& v = j_.at(key);
    if (!v.is_number()) fail(key, "expected a number, got " + show(v));
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(key, "expected a finite number, got " + show(v));
    return x;
  }
  double number(const char* key, double def) const { return has(key) ? number(key) : def; }
  /// A number checked against a condition; `what` is e.g. "must be > 0".
  template <class Pred>
  double number_if(const char* key, Pred ok, const char* what) const {
    const double x = number(key);
    if (!ok(x)) fail(key, std::string(what) + ", got " + show(j_.at(key)));
    return x;
  }
  template <class Pred>
  double number_if(const char* key, double def, Pred ok, const char* what) const {
    return has(key) ? number_if(key, ok, what) : def;
  }

  static bool is_vec2(const nlohmann::json& v) {
    return v.is_array() && v.size() == 2 && v[0].is_number() && v[1].is_number() &&
           std::isfinite(v[0].get<double>()) && std::isfinite(v[1].get<double>());
  }
  Vec2 vec2(const char* key) const {
    if (!has(key)) fail(key, "required [x, y] is missing");
    const auto& v = j_.at(key);
    if (!is_vec2(v)) fail(key, "expected [x, y] with two finite numbers, got " + show(v));
    return {v[0].get<double>(), v[1].get<double>()};
  }
  Vec2 vec2(const char* key, const Vec2& def) const { return has(key) ? vec2(key) : def; }

  std::string string(const char* key) const {
    if (!has(key)) fail(key, "required string is missing");
    const auto& v = j_.at(key);
    if (!v.is_string()) fail(key, "expected a string, got " + show(v));
    return v.get<std::string>();
  }
  bool boolean(const char* key, bool def) const {
    if (!has(key)) return def;
    const auto& v = j_.at(key);
    if (!v.is_boolean()) fail(key, "expected true or false, got " + show(v));
    return v.get<bool>();
  }
  /// The object under `key` (required).
  JsonIn object(const char* key) const {
    if (!has(key)) fail(key, "required object is missing");
    const auto& v = j_.at(key);
    if (!v.is_object()) fail(key, "expected an object, got " + show(v));
    return JsonIn(v, at(key), ctx_);
  }
  /// The array under `key` (required, may be empty).
  const nlohmann::json& array(const char* key) const {
    if (!has(key)) fail(key, "required array is missing");
    const auto& v = j_.at(key);
    if (!v.is_array()) fail(key, "expected an array, got " + show(v));
    return v;
  }

 private:
  const nlohmann::json& j_;
  std::string path_;
  std::string ctx_;
};

}  // namespace pinsim::sdf
