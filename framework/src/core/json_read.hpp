// Typed reading of JSON values with locations, so every error names the file and JSON path.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <string>

#include "core/input_error.hpp"

namespace pinsim {

/// A location in a JSON file: "scene.json: forces[2].params.k". `scene` says the file is a
/// scene: its errors are then SceneError, else InputError (a rubric, a bench config).
struct Loc {
  std::string file;
  std::string path;
  bool scene = false;
  Loc operator/(const std::string& key) const {
    return {file, path.empty() ? key : path + "." + key, scene};
  }
  Loc operator[](std::size_t i) const {
    return {file, path + "[" + std::to_string(i) + "]", scene};
  }
  std::string str() const { return file + ": " + (path.empty() ? "(top level)" : path); }
  /// Throws the input error "<file>: <path>: <what>".
  [[noreturn]] void fail(const std::string& what) const {
    if (scene) throw SceneError(str() + ": " + what);
    throw InputError(str() + ": " + what);
  }
};

/// "got <type> <value>" for messages.
std::string describe(const nlohmann::json& v);

/// Throws unless j is an object.
void require_object(const nlohmann::json& j, const Loc& at);
/// Throws at the first key of obj that is not in `allowed`, listing the allowed ones.
void check_keys(const nlohmann::json& obj, std::initializer_list<const char*> allowed,
                const Loc& at);

double read_number(const nlohmann::json& obj, const char* key, const Loc& at);
double read_number_or(const nlohmann::json& obj, const char* key, double def, const Loc& at);
Eigen::Vector2d read_vec2(const nlohmann::json& v, const Loc& at);
Eigen::Vector2d read_vec2_or(const nlohmann::json& obj, const char* key, const Eigen::Vector2d& def,
                             const Loc& at);
std::string read_string_or(const nlohmann::json& obj, const char* key, const std::string& def,
                           const Loc& at);
bool read_bool_or(const nlohmann::json& obj, const char* key, bool def, const Loc& at);
/// A non-negative integer.
uint64_t read_count_or(const nlohmann::json& obj, const char* key, uint64_t def, const Loc& at);

/// Text that is not JSON at all (a syntax error), as opposed to JSON that breaks a rule
/// (a duplicate key, too deep, a number out of range), which is a plain InputError.
class JsonSyntaxError : public InputError {
 public:
  using InputError::InputError;
};

/// Limits of parse_json_text (documented in README's Scenes section). The sizes bound the
/// memory a document takes once parsed: about 16 bytes per number, 80 per object member.
struct JsonLimits {
  std::size_t max_depth = 256;         ///< nesting of arrays and objects
  std::size_t max_bytes = 256u << 20;  ///< size of the text
  std::size_t max_values = 1'000'000;  ///< values and keys ($PINSIM_JSON_MAX_VALUES)
  std::size_t max_array = 1'000'000;   ///< entries of one array ($PINSIM_JSON_MAX_ARRAY)
  std::size_t max_string = 1u << 20;   ///< bytes of one string or key ($PINSIM_JSON_MAX_STRING)

  /// The defaults, with max_values, max_array and max_string taken from the environment
  /// variables named above when they are set (a positive integer; anything else is a
  /// SceneError naming the variable).
  static JsonLimits from_environment();
};

/// Parses JSON text with comments allowed, strictly: a syntax error or a number beyond a
/// double's range names file:line:column; a duplicate key, or nesting deeper than
/// limits.max_depth, names file and JSON path. Nesting is limited while parsing, before
/// anything recursive (copy, dump, destruction) can meet it. Throws JsonSyntaxError for
/// text that is not JSON, InputError for the rest.
nlohmann::json parse_json_text(const std::string& text, const std::string& label,
                               const JsonLimits& limits = JsonLimits::from_environment());

/// The file parsed by parse_json_text with its default limits (messages name the file).
/// Throws InputError if it is not a regular file or cannot be read.
nlohmann::json read_json_file(const std::filesystem::path& file);

}  // namespace pinsim
