#include "core/json_read.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <set>
#include <vector>

#include "core/bounded_read.hpp"

namespace pinsim {

std::string describe(const nlohmann::json& v) {
  std::string s = v.dump();
  if (s.size() > 60) s = s.substr(0, 57) + "...";
  return std::string("got ") + v.type_name() + " " + s;
}

void require_object(const nlohmann::json& j, const Loc& at) {
  if (!j.is_object()) at.fail("expected an object, " + describe(j));
}

void check_keys(const nlohmann::json& obj, std::initializer_list<const char*> allowed,
                const Loc& at) {
  for (const auto& [key, _] : obj.items()) {
    bool ok = false;
    for (const char* a : allowed) ok = ok || key == a;
    if (ok) continue;
    std::string list;
    for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    (at / key).fail("unknown key (expected one of: " + list + ")");
  }
}

static double as_number(const nlohmann::json& v, const Loc& at) {
  if (!v.is_number()) at.fail("expected a number, " + describe(v));
  const double d = v.get<double>();
  if (!std::isfinite(d)) at.fail("expected a finite number");
  return d;
}

double read_number(const nlohmann::json& obj, const char* key, const Loc& at) {
  if (!obj.contains(key)) (at / key).fail("required number is missing");
  return as_number(obj.at(key), at / key);
}

double read_number_or(const nlohmann::json& obj, const char* key, double def, const Loc& at) {
  return obj.contains(key) ? as_number(obj.at(key), at / key) : def;
}

Eigen::Vector2d read_vec2(const nlohmann::json& v, const Loc& at) {
  if (!v.is_array() || v.size() != 2) at.fail("expected [x, y], " + describe(v));
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
  if (!v.is_string()) (at / key).fail("expected a string, " + describe(v));
  return v.get<std::string>();
}

bool read_bool_or(const nlohmann::json& obj, const char* key, bool def, const Loc& at) {
  if (!obj.contains(key)) return def;
  const auto& v = obj.at(key);
  if (!v.is_boolean()) (at / key).fail("expected true or false, " + describe(v));
  return v.get<bool>();
}

uint64_t read_count_or(const nlohmann::json& obj, const char* key, uint64_t def, const Loc& at) {
  if (!obj.contains(key)) return def;
  const auto& v = obj.at(key);
  if (!v.is_number_integer() || v.get<long long>() < 0)
    (at / key).fail("expected a non-negative integer, " + describe(v));
  return v.get<uint64_t>();
}

namespace {

/// "line:column" of a byte offset (1-based, as editors count).
std::string line_col(const std::string& text, std::size_t byte) {
  std::size_t line = 1, col = 1;
  for (std::size_t i = 0; i + 1 < byte && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      col = 1;
    } else {
      ++col;
    }
  }
  return std::to_string(line) + ":" + std::to_string(col);
}

/// Builds the document through nlohmann's own DOM builder, refusing duplicate keys and
/// nesting deeper than the limit as they are met, and keeping the JSON path of the value
/// being read for messages.
class StrictSax : public nlohmann::json_sax<nlohmann::json> {
 public:
  StrictSax(nlohmann::json& out, const JsonLimits& limits) : dom_(out, true), limits_(limits) {}

  bool null() override { return value() && dom_.null(); }
  bool boolean(bool v) override { return value() && dom_.boolean(v); }
  bool number_integer(number_integer_t v) override { return value() && dom_.number_integer(v); }
  bool number_unsigned(number_unsigned_t v) override { return value() && dom_.number_unsigned(v); }
  bool number_float(number_float_t v, const string_t& s) override {
    return value() && dom_.number_float(v, s);
  }
  bool string(string_t& v) override { return value() && short_enough(v) && dom_.string(v); }
  bool binary(binary_t& v) override { return value() && dom_.binary(v); }
  bool start_object(std::size_t n) override {
    if (!value() || !open(true)) return false;
    return dom_.start_object(n);
  }
  bool key(string_t& k) override {
    if (!short_enough(k) || !counted()) return false;
    Frame& f = frames_.back();
    if (!f.keys.insert(k).second) {
      f.key = k;
      problem_ = "duplicate key \"" + k + "\" (each key may appear once)";
      return false;
    }
    f.key = k;
    return dom_.key(k);
  }
  bool end_object() override {
    frames_.pop_back();
    return dom_.end_object();
  }
  bool start_array(std::size_t n) override {
    if (!value() || !open(false)) return false;
    return dom_.start_array(n);
  }
  bool end_array() override {
    frames_.pop_back();
    return dom_.end_array();
  }
  bool parse_error(std::size_t pos, const std::string& token,
                   const nlohmann::detail::exception& e) override {
    error_pos_ = pos;
    error_token_ = token;
    error_id_ = e.id;
    error_ = e.what();
    return false;
  }

  const std::string& problem() const { return problem_; }
  std::size_t error_pos() const { return error_pos_; }
  /// The token the error is about (its last byte is at error_pos()).
  const std::string& error_token() const { return error_token_; }
  int error_id() const { return error_id_; }
  const std::string& error() const { return error_; }
  /// The JSON path of the value being read: "forces[2].params.k".
  std::string path() const { return path_of(false); }
  /// The JSON path of the value whose text is being read when the parser fails inside it
  /// (a number out of range): in an array, the entry after the last one counted.
  std::string path_of_next() const { return path_of(true); }

 private:
  struct Frame {
    bool object;
    std::size_t index = 0;  ///< arrays: values seen (the current one is index - 1)
    std::string key;
    std::set<std::string> keys;
  };
  std::string path_of(bool next) const {
    std::string p;
    for (std::size_t k = 0; k < frames_.size(); ++k) {
      const Frame& f = frames_[k];
      // appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) about
      // "[" + std::to_string(...) inlined here
      if (f.object) {
        if (f.key.empty()) continue;
        if (!p.empty()) p += '.';
        p += f.key;
      } else if (next && k + 1 == frames_.size()) {
        p += '[';
        p += std::to_string(f.index);
        p += ']';
      } else if (f.index > 0) {
        p += '[';
        p += std::to_string(f.index - 1);
        p += ']';
      }
    }
    return p;
  }
  /// A value or an object key: count it in the document.
  bool counted() {
    if (++values_ <= limits_.max_values) return true;
    problem_ = "more than " + std::to_string(limits_.max_values) +
               " values and keys in the document (the limit; $PINSIM_JSON_MAX_VALUES raises it)";
    return false;
  }
  /// A value begins: count it in its array (so a message's path names it), then in the
  /// document.
  bool value() {
    if (!frames_.empty() && !frames_.back().object && ++frames_.back().index > limits_.max_array) {
      problem_ = "an array of more than " + std::to_string(limits_.max_array) +
                 " entries (the limit; $PINSIM_JSON_MAX_ARRAY raises it)";
      return false;
    }
    return counted();
  }
  bool short_enough(const string_t& v) {
    if (v.size() <= limits_.max_string) return true;
    problem_ = "a string of " + std::to_string(v.size()) + " bytes, longer than the limit of " +
               std::to_string(limits_.max_string) + " ($PINSIM_JSON_MAX_STRING raises it)";
    return false;
  }
  bool open(bool object) {
    if (frames_.size() >= limits_.max_depth) {
      problem_ = "nested deeper than " + std::to_string(limits_.max_depth) +
                 " levels of arrays and objects (the limit)";
      return false;
    }
    frames_.push_back(Frame{object, 0, {}, {}});
    return true;
  }

  nlohmann::detail::json_sax_dom_parser<nlohmann::json> dom_;
  const JsonLimits& limits_;
  std::size_t values_ = 0;
  std::vector<Frame> frames_;
  std::string problem_, error_, error_token_;
  std::size_t error_pos_ = 0;
  int error_id_ = 0;
};

}  // namespace

JsonLimits JsonLimits::from_environment() {
  JsonLimits l;
  const std::pair<const char*, std::size_t*> vars[] = {{"PINSIM_JSON_MAX_VALUES", &l.max_values},
                                                       {"PINSIM_JSON_MAX_ARRAY", &l.max_array},
                                                       {"PINSIM_JSON_MAX_STRING", &l.max_string}};
  for (const auto& [name, field] : vars) {
    const char* v = std::getenv(name);
    if (v == nullptr || *v == '\0') continue;
    const std::string text = v;
    if (text.size() > 18 || text.find_first_not_of("0123456789") != std::string::npos ||
        std::stoull(text) == 0)
      throw SceneError(std::string("$") + name + "=" + text +
                       ": expected a positive integer (at most 18 digits)");
    *field = std::stoull(text);
  }
  return l;
}

nlohmann::json parse_json_text(const std::string& text, const std::string& label,
                               const JsonLimits& limits) {
  if (text.size() > limits.max_bytes)
    throw InputError(label + ": " + std::to_string(text.size()) +
                     " bytes, larger than the limit of " + std::to_string(limits.max_bytes) +
                     " bytes for a JSON file");
  nlohmann::json out;
  StrictSax sax(out, limits);
  bool ok = false;
  try {
    ok = nlohmann::json::sax_parse(text, &sax, nlohmann::json::input_format_t::json, true,
                                   /*ignore_comments=*/true);
  } catch (const nlohmann::json::exception& e) {
    throw JsonSyntaxError(label + ": malformed JSON: " + e.what());
  }
  if (ok) return out;
  if (!sax.problem().empty()) {
    const std::string path = sax.path();
    throw InputError(label + ": " + (path.empty() ? "(top level)" : path) + ": " + sax.problem());
  }
  std::string what = sax.error();
  const std::string where = label + ":" + line_col(text, sax.error_pos()) + ": ";
  if (sax.error_id() == 406) {
    // out_of_range.406: a number literal beyond a double's range (about 1.8e308); the
    // position given is the literal's last byte, the message names where it starts.
    const std::string& lit = sax.error_token();
    const std::size_t start = sax.error_pos() + 1 - std::min(sax.error_pos(), lit.size());
    const std::string path = sax.path_of_next();
    throw InputError(label + ":" + line_col(text, start) + ": " +
                     (path.empty() ? "(top level)" : path) + ": number " + lit +
                     " is out of range: a double holds magnitudes up to 1.8e308");
  }
  if (auto p = what.find("syntax error"); p != std::string::npos) what = what.substr(p);
  throw JsonSyntaxError(where + "malformed JSON: " + what);
}

std::string read_json_text(std::istream& in, const std::string& label, std::size_t max_bytes) {
  std::string text;
  char buf[1 << 16];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    text.append(buf, static_cast<std::size_t>(in.gcount()));
    if (text.size() > max_bytes)
      throw InputError(label + ": larger than the limit of " + std::to_string(max_bytes) +
                       " bytes for a JSON file");
  }
  return text;
}

nlohmann::json read_json_file(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec))
    throw InputError(file.string() + ": not found or not a regular file");
  std::ifstream in(file, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!in.good() && !in.eof()) throw InputError(file.string() + ": cannot be read");
  return parse_json_text(text, file.string());
}

}  // namespace pinsim
