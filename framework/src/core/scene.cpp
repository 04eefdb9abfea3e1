#include "core/scene.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>

#include "core/bounded_read.hpp"
#include "core/data_files.hpp"
#include "core/format.hpp"
#include "core/json_read.hpp"
#include "core/set_path.hpp"
#include "core/trajectory_hdf5.hpp"
#include "core/value_limits.hpp"

namespace fs = std::filesystem;

namespace pinsim {

std::vector<std::string> split_set_path(const std::string& path) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : path) {
    if (c == '.' || c == '[' || c == ']') {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

namespace {

/// Nesting depth of a JSON value: 0 for a scalar, 1 + the deepest element's for an array or
/// object. Called on values from parse_json_text, so the recursion is bounded by its limit.
std::size_t nesting_depth(const nlohmann::json& v) {
  if (!v.is_structured()) return 0;
  std::size_t d = 0;
  for (const auto& e : v) d = std::max(d, nesting_depth(e));
  return d + 1;
}

bool is_index(const std::string& s) {
  return !s.empty() && s.find_first_not_of("0123456789") == std::string::npos;
}

PluginRef read_plugin_ref(const nlohmann::json& j, const Loc& at, const char* name_key) {
  PluginRef r;
  r.where = at.str();
  r.name = read_string_or(j, name_key, "", at);
  if (r.name.empty()) (at / name_key).fail("required plugin name is missing");
  r.library = read_string_or(j, "library", "", at);
  r.params = j.contains("params") ? j.at("params") : nlohmann::json::object();
  if (!r.params.is_object()) (at / "params").fail("expected an object, " + describe(r.params));
  return r;
}

void read_particles(const nlohmann::json& list, const Loc& at, ParticleList& out) {
  if (!list.is_array()) at.fail("expected an array of particles, " + describe(list));
  check_particle_count(out.size(), list.size(), at);
  for (std::size_t i = 0; i < list.size(); ++i) {
    const auto& p = list[i];
    const Loc pl = at[i];
    require_object(p, pl);
    check_keys(p, {"name", "x", "v", "mass", "radius", "pinned"}, pl);
    if (!p.contains("x")) (pl / "x").fail("required position [x, y] is missing");
    const Eigen::Vector2d x = read_vec2(p.at("x"), pl / "x");
    check_position(x, pl / "x");
    const Eigen::Vector2d v = read_vec2_or(p, "v", Eigen::Vector2d::Zero(), pl);
    check_velocity(v, pl / "v");
    const bool pinned = read_bool_or(p, "pinned", false, pl);
    const double mass = read_number_or(p, "mass", 1.0, pl);
    if (!(mass > 0.0)) (pl / "mass").fail("must be > 0, got " + p.at("mass").dump());
    check_mass(mass, pl / "mass");
    const double radius = read_number_or(p, "radius", 0.0, pl);
    if (!(radius >= 0.0)) (pl / "radius").fail("must be >= 0, got " + p.at("radius").dump());
    check_radius(radius, pl / "radius");
    out.add(x, v, pinned ? 0.0 : 1.0 / mass, radius);
  }
}

// time: {"dt" > 0, "duration" >= 0}, at most 1e12 steps.
void read_time(const nlohmann::json& d, const Loc& root, Scene& s) {
  if (!d.contains("time"))
    (root / "time").fail("required object {\"dt\", \"duration\"} is missing");
  const auto& t = d.at("time");
  require_object(t, root / "time");
  check_keys(t, {"dt", "duration"}, root / "time");
  s.dt = read_number(t, "dt", root / "time");
  if (!(s.dt > 0.0)) (root / "time" / "dt").fail("must be > 0, got " + t.at("dt").dump());
  s.duration = read_number(t, "duration", root / "time");
  if (!(s.duration >= 0.0))
    (root / "time" / "duration").fail("must be >= 0, got " + t.at("duration").dump());
  if (s.duration / s.dt > 1e12)
    (root / "time").fail("duration / dt is over 1e12 steps; check the units");
}

// backend: a name, or {"name", "library", "params"}; "none" if absent.
PluginRef read_backend(const nlohmann::json& d, const Loc& root) {
  if (!d.contains("backend"))
    return PluginRef{"none", "", nlohmann::json::object(), (root / "backend").str()};
  const auto& b = d.at("backend");
  if (b.is_string())
    return PluginRef{b.get<std::string>(), "", nlohmann::json::object(), (root / "backend").str()};
  require_object(b, root / "backend");
  check_keys(b, {"name", "library", "params"}, root / "backend");
  return read_plugin_ref(b, root / "backend", "name");
}

// plugin_path: folders, relative ones taken from the scene file's folder.
std::vector<fs::path> read_plugin_path(const nlohmann::json& d, const Loc& root,
                                       const fs::path& base_dir) {
  std::vector<fs::path> out;
  if (!d.contains("plugin_path")) return out;
  const auto& pp = d.at("plugin_path");
  if (!pp.is_array()) (root / "plugin_path").fail("expected a list of folders, " + describe(pp));
  for (std::size_t i = 0; i < pp.size(); ++i) {
    if (!pp[i].is_string()) (root / "plugin_path")[i].fail("expected a folder, " + describe(pp[i]));
    fs::path p = pp[i].get<std::string>();
    out.push_back(p.is_absolute() ? p : base_dir / p);
  }
  return out;
}

// particles, then bodies (each adds its particles and element sets; names are unique);
// at least one particle in all.
void read_particles_and_bodies(const nlohmann::json& d, const Loc& root, Scene& s) {
  if (d.contains("particles")) read_particles(d.at("particles"), root / "particles", s.particles);
  if (d.contains("bodies")) {
    const auto& bl = d.at("bodies");
    if (!bl.is_array()) (root / "bodies").fail("expected an array of bodies, " + describe(bl));
    for (std::size_t i = 0; i < bl.size(); ++i) {
      require_object(bl[i], (root / "bodies")[i]);
      const std::size_t before = s.particles.size();
      Body b = build_body(bl[i], (root / "bodies")[i].str(), s.particles);
      // (a body's particles come from its centre, origin or root and its sizes)
      for (std::size_t k = before; k < s.particles.size(); ++k)
        if (!(std::abs(s.particles.x[k].x()) <= kMaxCoordinate &&
              std::abs(s.particles.x[k].y()) <= kMaxCoordinate))
          ((root / "bodies")[i])
              .fail("puts its particle " + std::to_string(k - before) + " at (" +
                    num(s.particles.x[k].x()) + ", " + num(s.particles.x[k].y()) +
                    "), beyond the coordinate limit of " + num(kMaxCoordinate) + " in magnitude");
      for (const auto& other : s.bodies)
        if (!b.name.empty() && other.name == b.name)
          ((root / "bodies")[i] / "name").fail("a body named '" + b.name + "' already exists");
      s.bodies.push_back(std::move(b));
    }
  }
  if (s.particles.size() == 0)
    root.fail("the scene has no particles (give \"particles\" or \"bodies\")");
}

// forces: plugin references by "type", with their elements unresolved.
std::vector<ForceSpec> read_forces(const nlohmann::json& d, const Loc& root) {
  std::vector<ForceSpec> out;
  if (!d.contains("forces")) return out;
  const auto& fl = d.at("forces");
  if (!fl.is_array()) (root / "forces").fail("expected an array of forces, " + describe(fl));
  for (std::size_t i = 0; i < fl.size(); ++i) {
    const Loc fa = (root / "forces")[i];
    require_object(fl[i], fa);
    check_keys(fl[i], {"type", "library", "params", "elements", "name"}, fa);
    ForceSpec f;
    static_cast<PluginRef&>(f) = read_plugin_ref(fl[i], fa, "type");
    f.elements = fl[i].value("elements", nlohmann::json());
    out.push_back(std::move(f));
  }
  return out;
}

// What the backend gets, verbatim: obstacles (an array), inputs and contacts.
nlohmann::json read_backend_scene(const nlohmann::json& d, const Loc& root) {
  nlohmann::json out = nlohmann::json::object();
  for (const char* k : {"obstacles", "inputs", "contacts"})
    if (d.contains(k)) out[k] = d.at(k);
  if (out.contains("obstacles") && !out["obstacles"].is_array())
    (root / "obstacles").fail("expected an array of obstacles, " + describe(d.at("obstacles")));
  return out;
}

// output: {"every" >= 1, "format": "csv" | "hdf5", "compression": 0..9 (hdf5 only),
//          "events": "impacts" | "all" | "none"}.
void read_output(const nlohmann::json& d, const Loc& root, Scene& s) {
  if (!d.contains("output")) return;
  const auto& o = d.at("output");
  require_object(o, root / "output");
  check_keys(o, {"every", "format", "compression", "events"}, root / "output");
  s.output_every = read_count_or(o, "every", 1, root / "output");
  if (s.output_every == 0) (root / "output" / "every").fail("must be >= 1, got 0");
  s.output_format = read_string_or(o, "format", "csv", root / "output");
  if (s.output_format != "csv" && s.output_format != "hdf5")
    (root / "output" / "format")
        .fail("expected \"csv\" or \"hdf5\", got \"" + s.output_format + "\"");
  if (s.output_format == "hdf5" && !hdf5_supported())
    (root / "output" / "format")
        .fail("\"hdf5\" needs a pinsim built with HDF5 (PINSIM_WITH_HDF5=ON); use \"csv\"");
  if (o.contains("compression")) {
    const uint64_t level = read_count_or(o, "compression", 0, root / "output");
    if (level > 9)
      (root / "output" / "compression")
          .fail("expected a deflate level from 0 (none) to 9, got " + std::to_string(level));
    if (s.output_format != "hdf5")
      (root / "output" / "compression")
          .fail("applies to \"format\": \"hdf5\" only (this scene writes \"" + s.output_format +
                "\")");
    s.output_compression = static_cast<int>(level);
  }
  s.output_events = read_string_or(o, "events", s.output_events, root / "output");
  if (s.output_events != "impacts" && s.output_events != "all" && s.output_events != "none")
    (root / "output" / "events")
        .fail("expected \"impacts\", \"all\" or \"none\", got \"" + s.output_events + "\"");
}

// checks: {"energy_blowup" > 0, "energy_every" >= 1, "kinetic_growth" >= 2 or 0}.
void read_checks(const nlohmann::json& d, const Loc& root, Scene& s) {
  if (!d.contains("checks")) return;
  const auto& c = d.at("checks");
  require_object(c, root / "checks");
  check_keys(c, {"energy_blowup", "energy_every", "kinetic_growth"}, root / "checks");
  s.energy_blowup = read_number_or(c, "energy_blowup", s.energy_blowup, root / "checks");
  if (!(s.energy_blowup > 0.0)) (root / "checks" / "energy_blowup").fail("must be > 0");
  s.energy_every = read_count_or(c, "energy_every", s.energy_every, root / "checks");
  if (s.energy_every == 0) (root / "checks" / "energy_every").fail("must be >= 1, got 0");
  s.kinetic_growth = read_number_or(c, "kinetic_growth", s.kinetic_growth, root / "checks");
  if (!(s.kinetic_growth == 0.0 || (s.kinetic_growth >= 2.0 && s.kinetic_growth < HUGE_VAL)))
    (root / "checks" / "kinetic_growth")
        .fail("must be 0 (off) or a number >= 2, got " + num(s.kinetic_growth));
}

// xpbd: {"substeps": 1 to kMaxXpbdCount, "iterations": 1 to kMaxXpbdCount}, read whatever the
// integrator (a --integrator xpbd run uses them).
constexpr uint64_t kMaxXpbdCount = 100000;
void read_xpbd(const nlohmann::json& d, const Loc& root, Scene& s) {
  if (!d.contains("xpbd")) return;
  const auto& x = d.at("xpbd");
  require_object(x, root / "xpbd");
  check_keys(x, {"substeps", "iterations"}, root / "xpbd");
  auto count = [&](const char* key, uint32_t fallback) {
    const uint64_t v = read_count_or(x, key, fallback, root / "xpbd");
    if (v < 1 || v > kMaxXpbdCount)
      (root / "xpbd" / key)
          .fail("must be an integer from 1 to " + std::to_string(kMaxXpbdCount) + ", got " +
                x.at(key).dump());
    return static_cast<uint32_t>(v);
  };
  s.xpbd.substeps = count("substeps", s.xpbd.substeps);
  s.xpbd.iterations = count("iterations", s.xpbd.iterations);
}

}  // namespace

void apply_override(nlohmann::json& doc, const std::string& assignment, const std::string& label) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError("--set " + assignment + ": expected PATH=VALUE, e.g. time.dt=0.0005");
  const std::string path = assignment.substr(0, eq);
  const std::string text = assignment.substr(eq + 1);
  nlohmann::json value;
  try {
    value = parse_json_text(text, "--set " + path + "=");
  } catch (const JsonSyntaxError&) {
    value = text;  // a bare word is a string
    try {
      (void)value.dump();  // JSON text is UTF-8: anything else would fail later, unlocated
    } catch (const nlohmann::json::type_error&) {
      throw SceneError(label + ": --set " + path + ": the value is not valid UTF-8");
    }
  }
  const auto keys = split_set_path(path);
  if (keys.empty()) throw InputError("--set " + assignment + ": empty path");
  // Each key is a level: the document stays within the parser's nesting limit, so nothing
  // recursive (a copy, a dump) meets a deeper one.
  const std::size_t max_depth = JsonLimits{}.max_depth;
  if (keys.size() + nesting_depth(value) > max_depth)
    throw InputError(label + ": --set " + path.substr(0, 80) + (path.size() > 80 ? "..." : "") +
                     ": nests " + std::to_string(keys.size() + nesting_depth(value)) +
                     " levels deep, more than the limit of " + std::to_string(max_depth));
  nlohmann::json* cur = &doc;
  std::string walked;
  for (std::size_t k = 0; k < keys.size(); ++k) {
    const std::string& key = keys[k];
    const bool last = k + 1 == keys.size();
    if (cur->is_array()) {
      // (more than 18 digits cannot be an index of any array here, nor fit stoull)
      if (!is_index(key) || key.size() > 18 || std::stoull(key) >= cur->size())
        throw SceneError(label + ": --set " + path + ": " + walked + " has " +
                         std::to_string(cur->size()) + " entries, no index '" + key + "'");
      cur = &(*cur)[std::stoull(key)];
      walked += "[" + key + "]";
    } else if (cur->is_object() || cur->is_null()) {
      if (cur->is_null()) *cur = nlohmann::json::object();
      walked += (walked.empty() ? "" : ".") + key;
      if (!last && !cur->contains(key)) (*cur)[key] = nlohmann::json::object();
      cur = &(*cur)[key];
    } else {
      throw SceneError(label + ": --set " + path + ": " + walked + " is a " + cur->type_name() +
                       ", not an object or array");
    }
  }
  *cur = value;
}

uint64_t Scene::steps() const { return static_cast<uint64_t>(std::llround(duration / dt)); }

State Scene::initial_state() const {
  State s;
  const auto n = static_cast<Eigen::Index>(particles.size());
  s.x.resize(2, n);
  s.v.resize(2, n);
  s.inv_mass.resize(n);
  s.radius.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    s.x.col(i) = particles.x[static_cast<std::size_t>(i)];
    s.v.col(i) = particles.v[static_cast<std::size_t>(i)];
    s.inv_mass[i] = particles.inv_mass[static_cast<std::size_t>(i)];
    s.radius[i] = particles.radius[static_cast<std::size_t>(i)];
  }
  return s;
}

std::string Scene::obstacle_id(int64_t index) const {
  // Called for every event: look the array up in place (json::value would copy it).
  const auto it = backend_scene.is_object() ? backend_scene.find("obstacles") : backend_scene.end();
  if (it == backend_scene.end() || !it->is_array()) return "";
  const auto& obs = *it;
  if (index < 0 || static_cast<std::size_t>(index) >= obs.size()) return "";
  const auto& o = obs[static_cast<std::size_t>(index)];
  if (o.is_object() && o.contains("id") && o["id"].is_string()) return o["id"].get<std::string>();
  return "obstacles[" + std::to_string(index) + "]";
}

std::vector<uint32_t> Scene::resolve_elements(const ForceSpec& f, uint32_t arity) const {
  const std::string where = f.where + ".elements";
  const uint32_t n = static_cast<uint32_t>(particles.size());
  std::vector<uint32_t> out;
  const auto& e = f.elements;
  // Arity 0: whole bodies / closed rings of any length, each stored as its length and then
  // its indices (PINSIM_ARITY_VARIABLE).
  auto shape = [](uint32_t a) {
    return a == 0 ? std::string("whole bodies (elements of any length)")
                  : "elements of " + std::to_string(a) + " particles";
  };
  if (e.is_null()) {
    if (arity == 0)
      throw SceneError(where + ": plugin '" + f.name +
                       "' acts on whole bodies; give \"elements\": {\"body\": ..., \"set\": "
                       "\"boundary\"} or a list of particle lists");
    if (arity != 1)
      throw SceneError(where + ": plugin '" + f.name + "' acts on elements of " +
                       std::to_string(arity) +
                       " particles; give \"elements\": a list or {\"body\": ..., \"set\": ...}");
    for (uint32_t i = 0; i < n; ++i) out.push_back(i);
    return out;
  }
  if (e.is_object()) {
    if (!e.contains("body") || !e["body"].is_string())
      throw SceneError(where + ".body: expected the name of a body, " +
                       describe(e.value("body", nlohmann::json())));
    for (const auto& [k, _] : e.items())
      if (k != "body" && k != "set")
        throw SceneError(where + "." + k + ": unknown key (expected body, set)");
    const std::string body = e["body"].get<std::string>();
    const std::string set = e.value("set", arity == 1 ? std::string("particles") : std::string());
    for (const auto& b : bodies) {
      if (b.name != body) continue;
      if (set == "particles" && arity == 1) {
        for (uint32_t i = 0; i < b.count; ++i) out.push_back(b.first + i);
        return out;
      }
      auto it = b.sets.find(set);
      if (it == b.sets.end()) {
        std::string names = arity == 1 ? "particles" : "";
        for (const auto& [name, _s] : b.sets) names += (names.empty() ? "" : ", ") + name;
        throw SceneError(where + ".set: body '" + body + "' has no element set '" + set +
                         "' (it has: " + names + ")");
      }
      if (it->second.arity != arity)
        throw SceneError(where + ".set: set '" + set + "' of body '" + body + "' has " +
                         shape(it->second.arity) + ", but plugin '" + f.name + "' needs " +
                         shape(arity));
      return it->second.indices;
    }
    throw SceneError(where + ".body: no body named '" + body + "'");
  }
  if (!e.is_array()) throw SceneError(where + ": expected a list of elements, " + describe(e));
  for (std::size_t i = 0; i < e.size(); ++i) {
    const std::string ei = where + "[" + std::to_string(i) + "]";
    std::vector<nlohmann::json> items;
    if (arity == 1 && e[i].is_number()) {
      items.push_back(e[i]);
    } else if (arity == 0) {
      if (!e[i].is_array() || e[i].empty())
        throw SceneError(ei + ": expected a list of particle indices (a whole body), " +
                         describe(e[i]));
      items.assign(e[i].begin(), e[i].end());
      out.push_back(static_cast<uint32_t>(items.size()));
    } else {
      if (!e[i].is_array() || e[i].size() != arity)
        throw SceneError(ei + ": expected " + std::to_string(arity) + " particle indices, " +
                         describe(e[i]));
      items.assign(e[i].begin(), e[i].end());
    }
    for (const auto& idx : items) {
      if (!idx.is_number_integer() || idx.get<long long>() < 0 || idx.get<long long>() >= n)
        throw SceneError(ei + ": particle index must be an integer in [0, " + std::to_string(n) +
                         "), " + describe(idx));
      out.push_back(idx.get<uint32_t>());
    }
  }
  return out;
}

Scene parse_scene(const std::string& text, const std::string& label, const fs::path& base_dir,
                  const std::vector<std::string>& overrides) {
  Scene s;
  s.label = label;
  s.base_dir = base_dir;
  // The document with the --set overrides applied; only known top-level keys.
  s.doc = parse_json_text(text, label);
  for (const auto& o : overrides) apply_override(s.doc, o, label);
  const auto& d = s.doc;
  const Loc root{label, "", true};
  require_object(d, root);
  check_keys(d,
             {"$schema", "name", "description", "time", "integrator", "xpbd", "backend",
              "plugin_path", "particles", "bodies", "forces", "obstacles", "inputs", "contacts",
              "output", "checks", "crosscheck"},
             root);
  // Each part in turn: every error names its JSON path.
  s.name = read_string_or(d, "name", fs::path(label).stem().string(), root);
  s.description = read_string_or(d, "description", "", root);
  read_time(d, root, s);
  s.integrator = read_string_or(d, "integrator", "symplectic_euler", root);
  read_xpbd(d, root, s);
  s.backend = read_backend(d, root);
  s.plugin_path = read_plugin_path(d, root, base_dir);
  read_particles_and_bodies(d, root, s);
  s.forces = read_forces(d, root);
  s.backend_scene = read_backend_scene(d, root);
  read_output(d, root, s);
  read_checks(d, root, s);
  return s;
}

const std::string& scene_file_text(const fs::path& name) {
  // A relative name not found here is looked up among the shipped scenes (data_files.hpp).
  const fs::path file = find_data_file(name, "configs");
  static std::mutex mutex;
  static std::map<std::string, std::string> texts;
  const std::lock_guard<std::mutex> lock(mutex);
  if (const auto it = texts.find(file.string()); it != texts.end()) return it->second;
  std::error_code ec;
  if (!fs::exists(file, ec))
    throw SceneError(file.string() + ": scene file not found" +
                     (file.is_relative() ? " (nor in " + (data_dir() / "configs").string() + ")"
                                         : std::string()));
  if (fs::is_directory(file, ec))
    throw SceneError(file.string() + ": is a folder, expected a scene file");
  std::ifstream in(file);
  if (!in) throw SceneError(file.string() + ": cannot be read");
  // Bounded: the file may be a pipe (`run <(cmd)`) or a device that never ends.
  return texts.emplace(file.string(), read_json_text(in, file.string())).first->second;
}

Scene load_scene(const fs::path& name, const std::vector<std::string>& overrides) {
  const fs::path file = find_data_file(name, "configs");
  return parse_scene(scene_file_text(file), file.string(), fs::absolute(file).parent_path(),
                     overrides);
}

}  // namespace pinsim
