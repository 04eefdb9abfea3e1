// The one sweep driver that bench and stress share (configs, their cases' axes, the points
// of this shard, the CSV and its manifest, the report of a whole sweep), and its pieces that
// batch grading's shards and `pinsim merge` use too: sharding, CSV tables written
// atomically, shard manifests, strict merging, least-squares orders and gnuplot figures.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/json_read.hpp"
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

/// Parses "i/N" (0 <= i < N); throws InputError with the expected form.
Shard parse_shard(const std::string& text);

/// A CSV table: a header and rows of cells (no quoting needed: cells never hold commas).
struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  /// Index of a column; throws InputError if missing.
  std::size_t col(const std::string& name) const;
  /// The CSV text: header line, then one line per row.
  std::string text() const;
  /// Writes the CSV atomically (temp file + rename): readers never see half a table.
  void write(const std::filesystem::path& file) const;
  static Table read(const std::filesystem::path& file);
};

/// Writes `bytes` to a temporary file beside `file`, then renames it over `file`, so the
/// file is either the old one or the whole new one; every write, the close and the rename
/// checked. Creates the folder. Throws OutputError naming the file and the reason.
void write_atomically(const std::filesystem::path& file, const std::string& bytes);

/// 64-bit FNV-1a of `bytes` as 16 hex digits: identifies a sweep's inputs or a file's bytes.
std::string fingerprint(std::string_view bytes);

/// What one shard's CSV is: written as NAME.json beside NAME.csv after the CSV itself, so a
/// shard with a manifest that matches its CSV's bytes finished writing. `merge` trusts no
/// shard without one.
struct Manifest {
  std::string tool;        ///< "bench", "stress" or "grade"
  std::string sweep;       ///< fingerprint of the whole sweep's inputs (config, scenes, options)
  Shard shard;             ///< which shard of how many
  std::size_t points = 0;  ///< points (or submissions) of the whole sweep, all shards
  std::size_t rows = 0;    ///< rows of this shard's CSV
  std::string csv_hash;    ///< fingerprint of the CSV file's bytes
};

/// NAME.json for NAME.csv.
std::filesystem::path manifest_path(const std::filesystem::path& csv);

/// Writes a shard's table to `csv`, then its manifest (rows and csv_hash filled in here),
/// each atomically. A rerun of the shard replaces both; one killed between the two renames
/// leaves a manifest that no longer matches, which `merge` refuses.
void write_shard(const Table& t, const std::filesystem::path& csv, Manifest m);

/// The manifest beside `csv`; nullopt if there is none. Throws InputError if it is malformed.
std::optional<Manifest> read_manifest(const std::filesystem::path& csv);

/// Joins the shard CSVs of one sweep. Refuses (InputError naming the file and what is wrong)
/// a shard without a manifest or whose bytes differ from it, shards of different sweeps or
/// shard counts, a shard given twice, missing shards (named by index), different headers.
/// Rows are sorted by the first column: numerically when it is "point", else as text.
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
/// InputError naming `where` otherwise.
std::vector<double> numbers(const nlohmann::json& j, const std::string& where);

/// The list `key` from a case (`a`), else from the config's top level (`b`), else `def`.
std::vector<nlohmann::json> list_or(const nlohmann::json& a, const nlohmann::json& b,
                                    const char* key, const nlohmann::json& def);

/// The config's "cases"; throws InputError naming the file if it is not a list.
const nlohmann::json& cases(const Config& cfg);

/// What every case of a sweep crosses, backends outermost, dt innermost: each from the case,
/// else from the config's top level.
struct Axes {
  std::vector<nlohmann::json> backends;  ///< {"name": ...} objects; null: the scene's backend
  std::vector<std::string> integrators;  ///< default: symplectic_euler
  std::vector<double> dts;               ///< required, seconds
};

/// The axes of case `c`; `where` names it in messages ("bench.json: cases[2]").
Axes case_axes(const Config& cfg, const nlohmann::json& c, const std::string& where);

/// Where case i of a config is, as messages name it.
struct CaseAt {
  std::string where;  ///< "bench.json: cases[2]"
  Loc at;             ///< the file and the JSON path cases[2]
};
CaseAt case_at(const Config& cfg, std::size_t i);

/// What makes shards parts of one sweep (Sweep::inputs): the tool's name, the config,
/// `options` (the command line's part, "\nrepeats=3", or ""), then every case's scene.
std::string sweep_inputs(const std::string& tool, const Config& cfg, const std::string& options,
                         const std::vector<const nlohmann::json*>& scenes);

/// What a sweep tool supplies; the driver does the rest.
struct Sweep {
  std::string tool;                  ///< "bench" or "stress": CSV name, manifest's tool
  std::vector<std::string> columns;  ///< the CSV header (first column "point")
  std::size_t points = 0;            ///< points of the whole sweep, all shards
  std::string inputs;                ///< what makes shards parts of one sweep (fingerprinted)
  /// Runs point i (and logs it); returns its CSV row.
  std::function<std::vector<std::string>(std::size_t)> run_point;
  /// Prints what a whole sweep's table shows and draws its figures into the folder.
  std::function<void(const Table&, const std::filesystem::path&)> report;
};

/// The CSV of one shard of `tool`: OUT/TOOL.csv for 0/1, else OUT/TOOL.shard-i-of-N.csv.
std::filesystem::path csv_path(const std::filesystem::path& out, const std::string& tool,
                               const Shard& shard);

/// Where a shard's finished points are kept while it runs (with a manifest):
/// OUT/TOOL.partial.csv for 0/1, else OUT/TOOL.partial.shard-i-of-N.csv (outside the
/// OUT/TOOL.shard-*.csv pattern that `merge` is given).
std::filesystem::path partial_path(const std::filesystem::path& out, const std::string& tool,
                                   const Shard& shard);

/// Runs the points `shard` owns, in order, keeping the finished ones in partial_path after
/// every point; then writes their CSV (a shard of many with its manifest), removes the
/// partial file and, for a whole sweep, prints the report. With `resume`, the points in the
/// partial file of an earlier, interrupted run of the same sweep and shard are taken from it
/// (InputError if it belongs to another sweep). A stop signal (stop_signals.hpp) ends the
/// sweep after the current point: the partial file then holds every finished point, the log
/// says how to continue, and drive returns the signal (0 when the sweep finished). `where`
/// (the config) names the log lines.
int drive(const Sweep& s, const Shard& shard, const std::filesystem::path& out,
          const std::string& where, bool resume = false);

/// A sweep tool's exit code once drive returned `signal`: 128 + the signal that stopped the
/// sweep, else the tool's own `code` (0, or 1 when a point failed and the tool says so).
int exit_code(int signal, int code);

}  // namespace pinsim::sweep
