#include "tools/sweep.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "core/input_error.hpp"
#include "core/json_read.hpp"
#include "core/output_file.hpp"
#include "core/stop_signals.hpp"

namespace fs = std::filesystem;

namespace pinsim::sweep {

std::string Shard::suffix() const {
  if (count == 1) return "";
  return ".shard-" + std::to_string(index) + "-of-" + std::to_string(count);
}

Shard parse_shard(const std::string& text) {
  Shard s;
  const auto slash = text.find('/');
  try {
    if (slash == std::string::npos) throw std::invalid_argument("no slash");
    std::size_t a = 0, b = 0;
    s.index = std::stoi(text.substr(0, slash), &a);
    s.count = std::stoi(text.substr(slash + 1), &b);
    if (a != slash || b != text.size() - slash - 1) throw std::invalid_argument("junk");
  } catch (const std::exception&) {
    throw InputError("--shard " + text + ": expected i/N, e.g. 0/4 (shard i of N, 0 <= i < N)");
  }
  if (s.count < 1 || s.index < 0 || s.index >= s.count)
    throw InputError("--shard " + text + ": need N >= 1 and 0 <= i < N");
  return s;
}

std::size_t Table::col(const std::string& name) const {
  for (std::size_t i = 0; i < header.size(); ++i)
    if (header[i] == name) return i;
  throw InputError("CSV table has no column '" + name + "'");
}

namespace {
std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  std::stringstream ss(line);
  while (std::getline(ss, cur, ',')) out.push_back(cur);
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}
}  // namespace

std::string Table::text() const {
  std::string out;
  auto line = [&out](const std::vector<std::string>& cells) {
    for (std::size_t i = 0; i < cells.size(); ++i) {
      if (i) out += ',';
      out += cells[i];
    }
    out += '\n';
  };
  line(header);
  for (const auto& r : rows) line(r);
  return out;
}

void Table::write(const fs::path& file) const { write_atomically(file, text()); }

void write_atomically(const fs::path& file, const std::string& bytes) {
  if (file.has_parent_path()) {
    std::error_code ec;
    fs::create_directories(file.parent_path(), ec);
    if (ec)
      throw OutputError(file.parent_path().string() + ": cannot create (" + ec.message() + ")");
  }
  write_file_atomically(file, bytes);
}

std::string fingerprint(std::string_view bytes) {
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a, 64 bit
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 1099511628211ull;
  }
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

fs::path manifest_path(const fs::path& csv) {
  fs::path m = csv;
  m.replace_extension(".json");
  return m;
}

void write_shard(const Table& t, const fs::path& csv, Manifest m) {
  const std::string bytes = t.text();
  m.rows = t.rows.size();
  m.csv_hash = fingerprint(bytes);
  const nlohmann::json j = {{"tool", m.tool},
                            {"sweep", m.sweep},
                            {"shard", m.shard.index},
                            {"shards", m.shard.count},
                            {"points", m.points},
                            {"rows", m.rows},
                            {"csv", csv.filename().string()},
                            {"csv_hash", m.csv_hash}};
  write_atomically(csv, bytes);
  write_atomically(manifest_path(csv), j.dump(1) + "\n");
}

std::optional<Manifest> read_manifest(const fs::path& csv) {
  const fs::path p = manifest_path(csv);
  if (!fs::exists(p)) return std::nullopt;
  Manifest m;
  try {
    const nlohmann::json j = read_json_file(p);
    if (!j.is_object()) throw std::runtime_error("not a JSON object");
    m.tool = j.at("tool").get<std::string>();
    m.sweep = j.at("sweep").get<std::string>();
    // Counts as non-negative integers within an int (an edited "shards": 1e18 once read as
    // -1486618624, a 1e300 was a double cast to int: undefined behaviour).
    const Loc at{p.string(), ""};
    for (const char* key : {"shard", "shards", "points", "rows"})
      if (!j.contains(key)) (at / key).fail("required");
    const uint64_t index = read_count_or(j, "shard", 0, at),
                   count = read_count_or(j, "shards", 0, at);
    if (!(count >= 1 && count <= INT_MAX && index < count))
      at.fail("expected shard i of N with N >= 1 and 0 <= i < N, got " + std::to_string(index) +
              " of " + std::to_string(count));
    m.shard.index = static_cast<int>(index);
    m.shard.count = static_cast<int>(count);
    m.points = read_count_or(j, "points", 0, at);
    m.rows = read_count_or(j, "rows", 0, at);
    m.csv_hash = j.at("csv_hash").get<std::string>();
  } catch (const InputError&) {
    throw;  // names the manifest and the JSON path already
  } catch (const std::exception& e) {
    throw InputError(p.string() + ": not a shard manifest (" + e.what() + ")");
  }
  return m;
}

Table Table::read(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file.string() + ": cannot be read");
  Table t;
  std::string line;
  if (!std::getline(in, line)) throw InputError(file.string() + ": empty, expected a CSV header");
  t.header = split(line);
  while (std::getline(in, line))
    if (!line.empty()) t.rows.push_back(split(line));
  return t;
}

Table merge(const std::vector<fs::path>& files) {
  if (files.empty()) throw InputError("merge: no CSV files given");
  Table all;
  std::optional<Manifest> first;
  std::map<int, fs::path> seen;  // shard index -> its file
  for (const fs::path& f : files) {
    std::ifstream probe(f);
    if (!probe) throw InputError(f.string() + ": cannot be read");
    const auto m = read_manifest(f);
    if (!m)
      throw InputError(f.string() + ": no shard manifest " + manifest_path(f).filename().string() +
                       " beside it (the shard did not finish writing, or it is not a shard "
                       "file); rerun that shard");
    std::stringstream bytes;
    bytes << probe.rdbuf();
    if (fingerprint(bytes.str()) != m->csv_hash)
      throw InputError(f.string() +
                       ": its bytes differ from its manifest (half rewritten, or "
                       "edited); rerun that shard");
    if (!first) {
      first = m;
    } else if (m->tool != first->tool || m->sweep != first->sweep ||
               m->shard.count != first->shard.count || m->points != first->points) {
      throw InputError(f.string() + ": from a different sweep than " + files[0].string() + " (" +
                       m->tool + " " + m->sweep + ", " + std::to_string(m->shard.count) +
                       " shards vs " + first->tool + " " + first->sweep + ", " +
                       std::to_string(first->shard.count) +
                       " shards): a different config, rubric, options or shard count");
    }
    if (seen.count(m->shard.index))
      throw InputError(f.string() + ": shard " + std::to_string(m->shard.index) +
                       " is given twice (also " + seen[m->shard.index].string() + ")");
    seen[m->shard.index] = f;
    Table t = Table::read(f);
    if (t.rows.size() != m->rows)
      throw InputError(f.string() + ": " + std::to_string(t.rows.size()) +
                       " rows, its manifest says " + std::to_string(m->rows));
    if (all.header.empty())
      all.header = t.header;
    else if (t.header != all.header)
      throw InputError(f.string() + ": its CSV header differs from " + files[0].string() +
                       "'s (a different sweep?)");
    all.rows.insert(all.rows.end(), t.rows.begin(), t.rows.end());
  }
  std::string missing;
  int n_missing = 0;
  for (int i = 0; i < first->shard.count; ++i)
    if (!seen.count(i)) {
      missing += (n_missing ? ", " : "") + std::to_string(i);
      ++n_missing;
    }
  if (n_missing)
    throw InputError("merge: incomplete set: shard" + std::string(n_missing > 1 ? "s " : " ") +
                     missing + " of " + std::to_string(first->shard.count) + " missing (" +
                     first->tool + " sweep " + first->sweep + ")");
  if (all.rows.size() != first->points)
    throw InputError("merge: the shards hold " + std::to_string(all.rows.size()) +
                     " rows, the sweep has " + std::to_string(first->points) + " points");
  const bool numeric = !all.header.empty() && all.header[0] == "point";
  std::stable_sort(all.rows.begin(), all.rows.end(), [numeric](const auto& a, const auto& b) {
    if (numeric)
      return std::strtoull(a[0].c_str(), nullptr, 10) < std::strtoull(b[0].c_str(), nullptr, 10);
    return a[0] < b[0];
  });
  return all;
}

namespace {

/// The whole text of a regular file (not a folder, a device or a pipe, which could be
/// endless); throws InputError naming `what` otherwise.
std::string read_config_text(const fs::path& file, const std::string& what) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) throw InputError(what + " not found or not a regular file");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(what + " cannot be read");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

Config load_config(const fs::path& file) {
  Config c;
  c.file = file;
  c.dir = fs::absolute(file).parent_path();
  // Strict JSON (nesting and size limited while parsing, duplicate keys and out-of-range
  // numbers refused with their place): a config's scene is copied and dumped recursively.
  c.doc = parse_json_text(read_config_text(file, file.string() + ": sweep config"), file.string());
  if (!c.doc.is_object()) throw InputError(file.string() + ": expected a JSON object");
  return c;
}

nlohmann::json scene_doc(const Config& cfg, const nlohmann::json& spec, fs::path& base_dir) {
  if (spec.is_object()) {
    base_dir = cfg.dir;
    return spec;
  }
  if (!spec.is_string())
    throw InputError(cfg.file.string() + ": \"scene\" must be a file name or a scene object");
  const fs::path p = cfg.dir / spec.get<std::string>();
  const std::string text = read_config_text(p, cfg.file.string() + ": scene " + p.string());
  base_dir = fs::absolute(p).parent_path();
  return parse_json_text(text, p.string());
}

Scene make_scene(nlohmann::json doc, const std::vector<std::pair<std::string, nlohmann::json>>& set,
                 const std::string& label, const fs::path& base_dir) {
  std::vector<std::string> overrides;
  for (const auto& [path, value] : set) overrides.push_back(path + "=" + value.dump());
  return parse_scene(doc.dump(), label, base_dir, overrides);
}

double loglog_slope(const std::vector<double>& x, const std::vector<double>& y) {
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size() && i < y.size(); ++i) {
    if (!(x[i] > 0.0) || !(y[i] > 0.0) || !std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    const double a = std::log(x[i]), b = std::log(y[i]);
    n += 1;
    sx += a;
    sy += b;
    sxx += a * a;
    sxy += a * b;
  }
  const double den = n * sxx - sx * sx;
  if (n < 2 || !(den > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  return (n * sxy - sx * sy) / den;
}

bool run_gnuplot(const fs::path& script) {
  if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) {
    spdlog::warn(
        "gnuplot not found: figure skipped (install Debian's gnuplot-nox, then run "
        "`gnuplot {}`)",
        script.string());
    return false;
  }
  const std::string cmd =
      "cd '" + script.parent_path().string() + "' && gnuplot '" + script.filename().string() + "'";
  if (std::system(cmd.c_str()) != 0) {
    spdlog::warn("gnuplot failed on {}: figure skipped", script.string());
    return false;
  }
  return true;
}

std::vector<double> numbers(const nlohmann::json& j, const std::string& where) {
  if (!j.is_array() || j.empty())
    throw InputError(where + ": expected a non-empty list of numbers");
  std::vector<double> out;
  for (const auto& x : j) {
    if (!x.is_number() || !(x.get<double>() > 0.0))
      throw InputError(where + ": expected positive numbers, got " + x.dump());
    out.push_back(x.get<double>());
  }
  return out;
}

std::vector<nlohmann::json> list_or(const nlohmann::json& a, const nlohmann::json& b,
                                    const char* key, const nlohmann::json& def) {
  const nlohmann::json& l = a.contains(key) ? a[key] : b.contains(key) ? b[key] : def;
  return std::vector<nlohmann::json>(l.begin(), l.end());
}

const nlohmann::json& cases(const Config& cfg) {
  if (!cfg.doc.contains("cases") || !cfg.doc["cases"].is_array())
    throw InputError(cfg.file.string() + ".cases: expected a list of cases");
  return cfg.doc["cases"];
}

Axes case_axes(const Config& cfg, const nlohmann::json& c, const std::string& where) {
  const nlohmann::json& d = cfg.doc;
  Axes a;
  a.dts = numbers(c.contains("dt") ? c["dt"] : d.value("dt", nlohmann::json()), where + ".dt");
  for (const auto& in : list_or(c, d, "integrators", nlohmann::json::array({"symplectic_euler"})))
    a.integrators.push_back(in.get<std::string>());
  for (const auto& b : list_or(c, d, "backends", nlohmann::json::array({nlohmann::json()})))
    a.backends.push_back(b.is_string() ? nlohmann::json{{"name", b}} : b);
  return a;
}

CaseAt case_at(const Config& cfg, std::size_t i) {
  const std::string file = cfg.file.string();
  return {file + ": cases[" + std::to_string(i) + "]", Loc{file, "cases"}[i]};
}

std::string sweep_inputs(const std::string& tool, const Config& cfg, const std::string& options,
                         const std::vector<const nlohmann::json*>& scenes) {
  std::string s = tool + "\n" + cfg.doc.dump() + options;
  for (const nlohmann::json* scene : scenes) {
    s += '\n';
    s += scene->dump();
  }
  return s;
}

fs::path csv_path(const fs::path& out, const std::string& tool, const Shard& shard) {
  return out / (tool + shard.suffix() + ".csv");
}

fs::path partial_path(const fs::path& out, const std::string& tool, const Shard& shard) {
  return out / (tool + ".partial" + shard.suffix() + ".csv");
}

namespace {

/// The rows of an interrupted run of this shard, by point, from its partial CSV; empty when
/// there is none. Throws InputError if it belongs to another sweep or shard.
std::map<std::size_t, std::vector<std::string>> finished_points(const fs::path& partial,
                                                                const Manifest& want) {
  std::map<std::size_t, std::vector<std::string>> rows;
  std::error_code ec;
  if (!fs::exists(partial, ec)) return rows;
  const auto m = read_manifest(partial);
  if (!m)
    throw InputError(partial.string() + ": no manifest " +
                     manifest_path(partial).filename().string() +
                     " beside it; remove it, or run without --continue");
  if (m->tool != want.tool || m->sweep != want.sweep || m->shard.index != want.shard.index ||
      m->shard.count != want.shard.count || m->points != want.points)
    throw InputError(partial.string() +
                     ": from a different sweep (another config, options or shard); remove it, "
                     "or run without --continue");
  const Table t = Table::read(partial);
  for (const auto& r : t.rows)
    if (!r.empty()) rows[std::strtoull(r[0].c_str(), nullptr, 10)] = r;
  return rows;
}

}  // namespace

int drive(const Sweep& s, const Shard& shard, const fs::path& out, const std::string& where,
          bool resume) {
  std::size_t mine = 0;
  for (std::size_t i = 0; i < s.points; ++i) mine += shard.owns(i);
  Manifest m;
  m.tool = s.tool;
  m.sweep = fingerprint(s.inputs);
  m.shard = shard;
  m.points = s.points;
  const fs::path partial = partial_path(out, s.tool, shard);
  std::map<std::size_t, std::vector<std::string>> done;
  if (resume) {
    done = finished_points(partial, m);
    spdlog::info("{}: resuming: {} of this shard's {} points already done ({})", where, done.size(),
                 mine, partial.string());
  } else if (std::error_code ec; fs::exists(partial, ec)) {
    spdlog::info("{}: replacing {} of an interrupted sweep (pass --continue to continue it)", where,
                 partial.string());
  }
  spdlog::info("{}: {} points, this shard ({}/{}) runs {}", where, s.points, shard.index,
               shard.count, mine - std::min(mine, done.size()));
  Table t;
  t.header = s.columns;
  const std::atomic<int>& stop = stop_signal();
  int sig = 0;
  for (std::size_t i = 0; i < s.points; ++i) {
    if (!shard.owns(i)) continue;
    if (const auto it = done.find(i); it != done.end()) {
      t.rows.push_back(it->second);
      continue;
    }
    if ((sig = stop.load()) != 0) break;
    t.rows.push_back(s.run_point(i));
    // Every finished point on disk at once, so an interrupted sweep loses none.
    write_shard(t, partial, m);
  }
  // A stopped sweep never writes its result, even when the signal came during its last
  // point: a cancelled shard is one without a result, and --continue completes it.
  if (sig == 0) sig = stop.load();
  if (sig != 0) {
    write_shard(t, partial, m);
    std::string again = "pinsim " + s.tool + " " + where + " --out " + out.string();
    if (shard.count > 1)
      again += " --shard " + std::to_string(shard.index) + "/" + std::to_string(shard.count);
    spdlog::warn(
        "{}: stopped by {} after {} of this shard's {} points; the finished points are in {} "
        "(with its manifest); continue with: {} --continue",
        where, signal_name(sig), t.rows.size(), mine, partial.string(), again);
    return sig;
  }
  const fs::path csv = csv_path(out, s.tool, shard);
  if (shard.count == 1)
    t.write(csv);
  else
    write_shard(t, csv, m);
  std::error_code ec;
  fs::remove(partial, ec);
  fs::remove(manifest_path(partial), ec);
  spdlog::info("wrote {}", csv.string());
  if (shard.count == 1)
    s.report(t, out);
  else
    spdlog::info("shard done; after all shards: pinsim merge --out {} {}/{}.shard-*.csv",
                 out.string(), out.string(), s.tool);
  return 0;
}

int exit_code(int signal, int code) { return signal != 0 ? stop_exit_code(signal) : code; }

}  // namespace pinsim::sweep
