// pinsim gradescope-pack --rubric R [--out autograder.zip] [--source DIR]
// Writes a Gradescope autograder zip for one rubric: setup.sh and run_autograder at its top
// level (made from scripts/gradescope/*.in, the rubric written into run_autograder), and the
// part of the source tree that builds `pinsim` and the plugins the rubric loads itself.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <set>
#include <sstream>

#include "commands.hpp"
#include "core/input_error.hpp"
#include "core/output_file.hpp"
#include "core/scene.hpp"
#include "grading/rubric.hpp"

namespace fs = std::filesystem;

namespace pinsim::cli {
namespace {

struct PackArgs {
  std::string rubric, out = "autograder.zip", source = PINSIM_SOURCE_DIR;
};

// What builds `pinsim` and the SDK: the build files and the framework without the web engine
// and the adjoint library (neither is part of `pinsim`), and the scene compiled into it.
const std::array<const char*, 12> kFrameworkParts = {"CMakeLists.txt",
                                                     "cmake/PinsimPlugin.cmake",
                                                     "cmake/pinsimConfig.cmake.in",
                                                     "framework/CMakeLists.txt",
                                                     "framework/include",
                                                     "framework/src/core",
                                                     "framework/src/scene_field",
                                                     "framework/src/tools",
                                                     "framework/src/grading",
                                                     "framework/src/pictures",
                                                     "framework/src/cli",
                                                     "configs/pinball.json"};

// ---- A zip archive (PKWARE APPNOTE 6.3), entries stored without compression. ----

std::uint32_t crc32(std::string_view data) {
  static const auto table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  std::uint32_t c = 0xFFFFFFFFu;
  for (const char ch : data) c = table[(c ^ static_cast<unsigned char>(ch)) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

void put16(std::string& s, std::uint32_t v) {
  s += static_cast<char>(v & 0xFF);
  s += static_cast<char>((v >> 8) & 0xFF);
}
void put32(std::string& s, std::uint32_t v) {
  put16(s, v & 0xFFFF);
  put16(s, v >> 16);
}

struct ZipEntry {
  std::string name;  ///< '/'-separated, relative
  std::string data;
  bool executable = false;
};

/// The archive's bytes. Every entry has the same time (1980-01-01 00:00, the earliest a zip
/// can say), so the same files give the same bytes; Unix modes 0644 or 0755.
std::string zip_bytes(const std::vector<ZipEntry>& entries) {
  constexpr std::uint32_t kDosDate = (0 << 9) | (1 << 5) | 1;  // 1980-01-01
  std::string out, central;
  for (const auto& e : entries) {
    if (e.data.size() >= 0xFFFFFFFFu || out.size() >= 0xFFFFFFFFu)
      throw InputError("gradescope-pack: " + e.name + " is too large for a zip without ZIP64");
    const std::uint32_t crc = crc32(e.data), size = static_cast<std::uint32_t>(e.data.size());
    const auto offset = static_cast<std::uint32_t>(out.size());
    const auto header = [&](std::string& s) {
      put16(s, 10);  // version needed: 1.0 (stored)
      put16(s, 0);   // flags
      put16(s, 0);   // method: stored
      put16(s, 0);   // time 00:00
      put16(s, kDosDate);
      put32(s, crc);
      put32(s, size);
      put32(s, size);
      put16(s, static_cast<std::uint32_t>(e.name.size()));
      put16(s, 0);  // extra field length
    };
    put32(out, 0x04034b50);
    header(out);
    out += e.name;
    out += e.data;
    put32(central, 0x02014b50);
    put16(central, (3 << 8) | 30);  // made by: Unix, 3.0
    header(central);
    put16(central, 0);  // comment length
    put16(central, 0);  // disk
    put16(central, 0);  // internal attributes
    put32(central, (e.executable ? 0100755u : 0100644u) << 16);
    put32(central, offset);
    central += e.name;
  }
  if (entries.size() >= 0xFFFF) throw InputError("gradescope-pack: too many files for a zip");
  const auto central_offset = static_cast<std::uint32_t>(out.size());
  out += central;
  put32(out, 0x06054b50);
  put16(out, 0);
  put16(out, 0);
  put16(out, static_cast<std::uint32_t>(entries.size()));
  put16(out, static_cast<std::uint32_t>(entries.size()));
  put32(out, static_cast<std::uint32_t>(central.size()));
  put32(out, central_offset);
  put16(out, 0);
  return out;
}

// ---- What goes in. ----

std::string read_whole(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  if (!in.good() && !in.eof()) throw InputError(p.string() + ": cannot read");
  if (!in.is_open()) throw InputError(p.string() + ": cannot open");
  return s.str();
}

/// Replaces every @KEY@ of `text` (a template in scripts/gradescope/); a key left over is an
/// error naming the template.
std::string fill(std::string text, const fs::path& file,
                 const std::map<std::string, std::string>& values) {
  for (const auto& [k, v] : values) {
    const std::string key = "@" + k + "@";
    for (std::size_t at = text.find(key); at != std::string::npos;
         at = text.find(key, at + v.size()))
      text.replace(at, key.size(), v);
  }
  std::smatch m;
  if (std::regex_search(text, m, std::regex("@[A-Z_]+@")))
    throw InputError(file.string() + ": unknown placeholder " + m.str());
  return text;
}

class Pack {
 public:
  explicit Pack(fs::path source) : source_(std::move(source)) {}

  /// Adds a file or every regular file under a folder (sorted), at its path in the source.
  void add(const fs::path& rel) {
    const fs::path p = source_ / rel;
    std::error_code ec;
    if (fs::is_directory(p, ec)) {
      for (auto it = fs::recursive_directory_iterator(p, ec);
           !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
        if (it->is_regular_file(ec)) add(it->path().lexically_relative(source_));
      if (ec) throw InputError(p.string() + ": cannot list (" + ec.message() + ")");
      return;
    }
    if (!fs::is_regular_file(p, ec))
      throw InputError(p.string() + ": not found (is " + source_.string() +
                       " a pinsim source tree? --source names it)");
    const auto perms = fs::status(p, ec).permissions();
    files_[rel.generic_string()] = {rel.generic_string(), read_whole(p),
                                    (perms & fs::perms::owner_exec) != fs::perms::none};
  }
  void add_generated(const std::string& name, std::string text, bool executable) {
    files_[name] = {name, std::move(text), executable};
  }
  std::vector<ZipEntry> entries() const {
    std::vector<ZipEntry> v;
    for (const auto& [name, e] : files_) v.push_back(e);
    return v;
  }
  const fs::path& source() const { return source_; }

 private:
  fs::path source_;
  std::map<std::string, ZipEntry> files_;  // sorted by name: the same tree, the same zip
};

/// The folder (plugins/NAME or backends/NAME) that builds plugin `name`, "" if none.
fs::path plugin_folder(const fs::path& source, const std::string& name) {
  std::error_code ec;
  for (const char* kind : {"plugins", "backends"})
    if (fs::is_regular_file(source / kind / name / "CMakeLists.txt", ec))
      return fs::path(kind) / name;
  return {};
}

/// `rel` (a path inside the zip's source) without "." and "..", or an error naming `what`
/// when it leads outside.
fs::path inside(const fs::path& rel, const std::string& what) {
  const fs::path n = rel.lexically_normal();
  if (n.empty() || n.is_absolute() || *n.begin() == "..")
    throw InputError(what + ": " + rel.string() +
                     " is outside the autograder's folder; keep scenes beside the rubric");
  return n;
}

int pack_command(const PackArgs& a) {
  const fs::path source = fs::absolute(a.source).lexically_normal();
  const fs::path rubric_file = fs::absolute(a.rubric).lexically_normal();
  const Rubric rubric = load_rubric(rubric_file);  // InputError naming the file and JSON path
  Pack pack(source);
  for (const char* part : kFrameworkParts) pack.add(part);

  // The rubric and its scenes: where they are in the source tree, or, for a rubric of the
  // course's own elsewhere, under rubric/ with the scenes at the same relative paths.
  const fs::path rel_to_source = rubric_file.lexically_relative(source);
  const bool in_tree = !rel_to_source.empty() && *rel_to_source.begin() != "..";
  const fs::path rubric_zip = in_tree ? rel_to_source : fs::path("rubric") / rubric_file.filename();
  const auto add_beside_rubric = [&](const fs::path& rel, const std::string& what) {
    const fs::path zip = inside(rubric_zip.parent_path() / rel, what);
    const fs::path file = rubric_file.parent_path() / rel;
    pack.add_generated(zip.generic_string(), read_whole(file), false);
  };
  add_beside_rubric(rubric_file.filename(), rubric_file.string());
  std::set<std::string> plugins;
  std::map<std::string, std::string> needed_by;  // plugin -> what asks for it (for errors)
  const auto need = [&](const std::string& name, const std::string& who) {
    if (name.empty() || plugins.count(name)) return;
    plugins.insert(name);
    needed_by[name] = who;
  };
  std::set<fs::path> scenes;
  for (const auto& t : rubric.tests) {
    const std::string who = rubric_file.string() + ": test '" + t.name + "'";
    for (const char* k : {"reference", "second_opinion"})
      if (t.spec.contains(k)) need(t.spec.at(k).get<std::string>(), who);
    if (!t.spec.contains("scene")) continue;
    const fs::path rel = t.spec.at("scene").get<std::string>();
    if (!scenes.insert(rel).second) continue;
    add_beside_rubric(rel, who);
    const Scene s = load_scene(rubric_file.parent_path() / rel);
    const std::string scene_who = (rubric_file.parent_path() / rel).string();
    need(s.backend.name, scene_who);
    for (const auto& f : s.forces) need(f.name, scene_who);
  }

  // Each plugin's folder, and the folders whose libraries it links (pinsim_NAME_impl).
  std::set<fs::path> folders;
  std::vector<std::string> todo(plugins.begin(), plugins.end());
  while (!todo.empty()) {
    const std::string name = todo.back();
    todo.pop_back();
    const fs::path dir = plugin_folder(source, name);
    if (dir.empty())
      throw InputError(needed_by[name] + " needs the plugin '" + name + "', which neither " +
                       (source / "plugins").string() + " nor " + (source / "backends").string() +
                       " builds");
    if (!folders.insert(dir).second) continue;
    const std::string cmake = read_whole(source / dir / "CMakeLists.txt");
    static const std::regex impl("pinsim_([a-z0-9_]+)_impl");
    for (auto it = std::sregex_iterator(cmake.begin(), cmake.end(), impl);
         it != std::sregex_iterator(); ++it)
      if (const std::string dep = (*it)[1];
          dep != name && !plugin_folder(source, dep).empty() && !plugins.count(dep)) {
        plugins.insert(dep);
        needed_by[dep] = (source / dir / "CMakeLists.txt").string();
        todo.push_back(dep);
      }
  }
  for (const auto& d : folders) pack.add(d);

  // setup.sh and run_autograder from their templates.
  std::string targets = "pinsim pinsim_scene_field", names, apt;
  for (const auto& p : plugins) {
    targets += " pinsim_plugin_" + p;
    names += (names.empty() ? "" : " ") + p;
  }
  if (plugins.count("box2d")) apt += " libbox2d-dev";
  const fs::path templates = source / "scripts/gradescope";
  const std::map<std::string, std::string> values = {{"RUBRIC", rubric_zip.generic_string()},
                                                     {"RUBRIC_NAME", rubric.name},
                                                     {"TARGETS", targets},
                                                     {"PLUGINS", names},
                                                     {"EXTRA_PACKAGES", apt}};
  for (const char* t : {"setup.sh", "run_autograder"}) {
    const fs::path in = templates / (std::string(t) + ".in");
    std::error_code ec;
    if (!fs::is_regular_file(in, ec))
      throw InputError(in.string() + ": not found (is " + source.string() +
                       " a pinsim source tree? --source names it)");
    pack.add_generated(t, fill(read_whole(in), in, values), true);
  }

  const std::vector<ZipEntry> entries = pack.entries();
  const std::string bytes = zip_bytes(entries);
  const fs::path out = fs::absolute(a.out);
  std::error_code ec;
  if (fs::is_directory(out, ec))
    throw InputError("--out " + out.string() + ": is a folder; name the zip file to write");
  if (!fs::is_directory(out.parent_path(), ec))
    throw InputError("--out " + out.string() + ": cannot write: its folder " +
                     out.parent_path().string() + " does not exist");
  try {
    write_file_atomically(out, bytes);  // a temporary beside it, renamed: never half a zip
  } catch (const OutputError& e) {
    throw InputError(std::string("--out ") + e.what());
  }
  spdlog::info("{}: {} files, {} KiB, for the rubric {} ({}); it builds pinsim and the plugins {}",
               out.string(), entries.size(), (bytes.size() + 1023) / 1024,
               rubric_zip.generic_string(), rubric.name, names);
  spdlog::info(
      "upload it as the autograder of a Gradescope programming assignment: base image "
      "Ubuntu 22.04, see docs/grading.md (Gradescope)");
  return 0;
}

}  // namespace

void add_gradescope_pack_command(CLI::App& app) {
  auto a = std::make_shared<PackArgs>();
  CLI::App* c = app.add_subcommand(
      "gradescope-pack",
      "Write a Gradescope autograder zip for one rubric (setup.sh, run_autograder and the "
      "source that builds the grader)");
  c->add_option("--rubric", a->rubric, "The rubric the autograder grades with")->required();
  c->add_option("--out,-o", a->out, "The zip to write (default autograder.zip)");
  c->add_option("--source", a->source,
                "The pinsim source tree to pack (default: the one this pinsim was built from)");
  c->callback([a] { throw CLI::RuntimeError(pack_command(*a)); });
}

}  // namespace pinsim::cli
