// Scenes: parsing and validating a scene file into an immutable model.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <pinsim/state.hpp>
#include <string>
#include <vector>

#include "core/bodies.hpp"
#include "core/input_error.hpp"

namespace pinsim {

/// A reference to a plugin in a scene: by name, optionally with an explicit library file.
struct PluginRef {
  std::string name;       ///< plugin name, e.g. "gravity"
  std::string library;    ///< explicit library path (resolved against the scene folder), or ""
  nlohmann::json params;  ///< as written in the scene (validated when the plugin is loaded)
  std::string where;      ///< location for messages, e.g. "scene.json: forces[2]"
};

/// One entry of "forces": the plugin and its raw element spec (resolved against its arity).
struct ForceSpec : PluginRef {
  nlohmann::json elements;  ///< null (all particles), a list, or {"body": ..., "set": ...}
};

/// The "xpbd" settings of a scene (used when the integrator is xpbd; docs/xpbd.md).
struct XpbdSettings {
  uint32_t substeps = 1;    ///< substeps per step, each with its own drift through the backend
  uint32_t iterations = 1;  ///< constraint sweeps per substep
};

struct Scene {
  std::string label;               ///< file name used in messages
  std::filesystem::path base_dir;  ///< folder relative paths are resolved against
  nlohmann::json doc;              ///< the whole document after --set overrides
  std::string name;
  std::string description;
  double dt = 0.0;        ///< time step, s
  double duration = 0.0;  ///< simulated time, s
  std::string integrator = "symplectic_euler";
  XpbdSettings xpbd;  ///< "xpbd": {"substeps", "iterations"}
  PluginRef backend;
  std::vector<std::filesystem::path> plugin_path;
  ParticleList particles;
  std::vector<Body> bodies;
  std::vector<ForceSpec> forces;
  nlohmann::json backend_scene;       ///< {"obstacles": [...], "inputs": [...], "contacts": {...}}
  uint64_t output_every = 1;          ///< write the trajectory every N steps
  std::string output_format = "csv";  ///< trajectory.csv ("csv") or trajectory.h5 ("hdf5")
  int output_compression = 0;         ///< trajectory.h5's deflate level, 0 (none) to 9
  /// events.csv: "impacts" (touch begins; spans in contacts.csv), "all" (every impulse) or
  /// "none"
  std::string output_events = "impacts";
  double energy_blowup = 1e3;    ///< stop when |E - E0| exceeds this many times the energy scale
  uint64_t energy_every = 100;   ///< check energy every N steps
  double kinetic_growth = 32.0;  ///< G of the per-step kinetic energy bound; 0 = off

  /// Number of steps: round(duration / dt).
  uint64_t steps() const;
  /// The initial state built from the particles and bodies.
  State initial_state() const;
  /// Resolves a force's element spec for a plugin of the given arity; throws SceneError.
  std::vector<uint32_t> resolve_elements(const ForceSpec& f, uint32_t arity) const;
  /// Obstacle id for an index (the "id" key, or "obstacles[i]").
  std::string obstacle_id(int64_t index) const;
};

/// Reads and parses a scene file. Overrides are "path=value" strings (path like
/// "time.dt" or "forces[0].params.k"; value parsed as JSON, else taken as a string).
/// The text of scene file `file`, read once per process (bounded, as every JSON file) and
/// kept: a command that looks at the scene twice (`--backend`, `share`) must not read a pipe
/// (`run <(cmd)`) twice, getting nothing the second time. SceneError if it cannot be read.
const std::string& scene_file_text(const std::filesystem::path& file);
Scene load_scene(const std::filesystem::path& file, const std::vector<std::string>& overrides = {});

/// Parses scene text; `label` names it in messages, `base_dir` resolves relative paths.
Scene parse_scene(const std::string& text, const std::string& label,
                  const std::filesystem::path& base_dir,
                  const std::vector<std::string>& overrides = {});

/// Applies one "path=value" override to a document; throws InputError (a malformed
/// assignment) or SceneError (a path the scene does not have) naming the path.
void apply_override(nlohmann::json& doc, const std::string& assignment, const std::string& label);

}  // namespace pinsim
