// Shared pieces of the bench and stress sweeps: configs, sharding, CSV tables, merging,
// least-squares orders and optional gnuplot figures.
#pragma once

#include <cstddef>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/scene.hpp"

namespace pinsim::sweep {

/// Which points this process runs: those with index % count == index_in.
struct Shard {
  int index = 0;  ///< 0-based shard number
  int count = 1;  ///< number of shards
  bool owns(std::size_t point) const {
    return static_cast<int>(point % static_cast<std::size_t>(count)) == index;
  }
  /// File-name suffix: "" for 0/1, else ".shard-2-of-8".
  std::string suffix() const;
};

/// Parses "i/N" (0 <= i < N); throws SceneError with the expected form.
Shard parse_shard(const std::string& text);

/// A CSV table: a header and rows of cells (no quoting needed: cells never hold commas).
struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  /// Index of a column; throws SceneError if missing.
  std::size_t col(const std::string& name) const;
  void write(const std::filesystem::path& file) const;
  static Table read(const std::filesystem::path& file);
};

/// Joins shard tables with identical headers, sorted by their first column ("point").
/// Throws SceneError naming the file whose header differs.
Table merge(const std::vector<std::filesystem::path>& files);

/// A sweep config: JSON with comments, its folder for relative scene paths.
struct Config {
  nlohmann::json doc;
  std::filesystem::path file;
  std::filesystem::path dir;
};
Config load_config(const std::filesystem::path& file);

/// The scene a case names: {"scene": "path/relative/to/config.json"} or {"scene": {...}}.
/// Returns the scene document (comments stripped) and the folder its paths resolve against.
nlohmann::json scene_doc(const Config& cfg, const nlohmann::json& scene_spec,
                         std::filesystem::path& base_dir);

/// Parses a scene document after setting every "path" = value in `set` (apply_override).
Scene make_scene(nlohmann::json doc, const std::vector<std::pair<std::string, nlohmann::json>>& set,
                 const std::string& label, const std::filesystem::path& base_dir);

/// Least-squares slope of log(y) against log(x) over the points with finite positive x, y;
/// NaN with fewer than 2 such points.
double loglog_slope(const std::vector<double>& x, const std::vector<double>& y);

/// Runs `gnuplot script` if gnuplot is on the PATH; otherwise logs that the figure was
/// skipped (install Debian's gnuplot-nox) and returns false. Never throws.
bool run_gnuplot(const std::filesystem::path& script);

/// A config's non-empty list of positive numbers (dt values, stiffnesses, speeds); throws
/// SceneError naming `where` otherwise.
std::vector<double> numbers(const nlohmann::json& j, const std::string& where);

/// The list `key` from a case (`a`), else from the config's top level (`b`), else `def`.
std::vector<nlohmann::json> list_or(const nlohmann::json& a, const nlohmann::json& b,
                                    const char* key, const nlohmann::json& def);

/// Shortest round-trip text for a double ("nan", "inf" for those).
std::string num(double x);

}  // namespace pinsim::sweep
