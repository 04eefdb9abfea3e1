#include "grading/private_paths.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <set>

#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "grading/sandbox.hpp"
#include "grading/sandbox_fallback.hpp"

namespace fs = std::filesystem;

namespace pinsim::grading {
namespace {

/// The file the grader would load for plugin `name`, or "" when none is found.
fs::path plugin_file(const std::string& name) {
  std::error_code ec;
  for (const auto& d : plugin_search_dirs())
    if (fs::is_regular_file(d / plugin_file_name(name), ec)) return d / plugin_file_name(name);
  return {};
}

}  // namespace

std::string exposed_private_paths(const Rubric& rubric, const fs::path& out) {
  std::error_code ec;
  ::chmod(out.c_str(), 0700);
  std::set<fs::path> reads = {rubric.file, rubric.file.parent_path()};
  std::set<std::string> plugins;
  for (const auto& t : rubric.tests) {
    for (const char* k : {"reference", "second_opinion"})
      if (t.spec.contains(k)) plugins.insert(t.spec.at(k).get<std::string>());
    if (!t.spec.contains("scene")) continue;
    const fs::path scene = rubric.file.parent_path() / t.spec.at("scene").get<std::string>();
    reads.insert(scene);
    try {
      const Scene s = load_scene(scene);
      plugins.insert(s.backend.name);
      for (const auto& f : s.forces) plugins.insert(f.name);
    } catch (const std::exception&) {
      // A scene the grader cannot read fails its test later; its path is still probed.
    }
  }
  for (const auto& p : plugins)
    if (const fs::path f = plugin_file(p); !f.empty()) reads.insert(f);
  for (const auto& d : plugin_search_dirs())
    if (fs::is_directory(d, ec)) reads.insert(d);
  std::vector<fallback::Probe> probes;
  for (const auto& p : reads) probes.push_back({p, false});
  probes.push_back({out, false});
  probes.push_back({out, true});
  const auto [uid, gid] = sandbox_ids();
  std::string list;
  for (const auto& p : fallback::reachable(probes, uid, gid))
    list += (list.empty() ? "" : ", ") + p.path.string() + (p.write ? " (write)" : " (read)");
  return list;
}

}  // namespace pinsim::grading
