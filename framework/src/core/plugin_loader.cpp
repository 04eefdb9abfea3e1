#include "core/plugin_loader.hpp"

#include <spdlog/spdlog.h>

#include <cstdlib>
#include <set>
#include <sstream>
#include <system_error>

#include "core/elf_check.hpp"
#include "core/plugin_table_check.hpp"
#include "core/static_plugins.hpp"

namespace fs = std::filesystem;

namespace pinsim {

std::string plugin_file_name(const std::string& name) { return "libpinsim_plugin_" + name + ".so"; }

std::vector<fs::path> plugin_search_dirs(const std::vector<fs::path>& scene_paths) {
  std::vector<fs::path> dirs(scene_paths.begin(), scene_paths.end());
  if (const char* env = std::getenv("PINSIM_PLUGIN_PATH")) {
    std::stringstream ss(env);
    std::string item;
    while (std::getline(ss, item, ':'))
      if (!item.empty()) dirs.emplace_back(item);
  }
  // An installed program's own plugins, relative to it (so a moved or copied install, a
  // container image or an unpacked tarball, finds its own), come before the build tree's: a
  // build tree left on the machine must not override what was installed. A program in the
  // build tree has no such directory beside it and gets the build tree's plugins.
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  fs::path rel;
  if (!ec) {
    rel = (exe.parent_path() / PINSIM_INSTALL_PLUGIN_RELDIR).lexically_normal();
    if (fs::is_directory(rel, ec))
      dirs.push_back(rel);
    else
      rel.clear();
  }
  dirs.emplace_back(PINSIM_BUILD_PLUGIN_DIR);
  if (rel != fs::path(PINSIM_INSTALL_PLUGIN_DIR)) dirs.emplace_back(PINSIM_INSTALL_PLUGIN_DIR);
  return dirs;
}

namespace {
/// Checks a plugin table (from a library's entry function or the static registry); `where`
/// names it in messages. Returns the table as the host reads it: a copy holding the entries
/// the plugin's table has, every later one absent.
std::shared_ptr<const pinsim_plugin> checked_table(const pinsim_plugin* raw,
                                                   const std::string& where) {
  if (raw == nullptr) throw LoadError(where + ": " PINSIM_ENTRY_SYMBOL " returned no table");
  // Nothing past abi_version and struct_size is read before the versions pass.
  if (const std::string bad = table_version_problem(*raw); !bad.empty())
    throw LoadError(where + ": " + bad);
  auto table = std::make_shared<const pinsim_plugin>(table_as_read(*raw));
  if (table->name == nullptr || table->create == nullptr || table->destroy == nullptr ||
      (table->kind != PINSIM_KIND_FORCE && table->kind != PINSIM_KIND_BACKEND))
    throw LoadError(where + ": malformed plugin table (name, kind, create or destroy missing)");
  if (table->kind == PINSIM_KIND_FORCE && table->force.add_force == nullptr)
    throw LoadError(where + ": force plugin without add_force");
  if (table->kind == PINSIM_KIND_BACKEND && table->backend.advance == nullptr)
    throw LoadError(where + ": backend plugin without advance");
  // Function pointers against capability flags, counts against their arrays.
  if (const std::string bad = plugin_table_problems(*table); !bad.empty())
    throw LoadError(where + ": inconsistent plugin table of '" + table->name + "': " + bad);
  return table;
}
}  // namespace

std::shared_ptr<const LoadedPlugin> load_plugin_file(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) throw LoadError("plugin file not found: " + file.string());

  // (the loader would map a truncated file past its end and die of SIGBUS)
  if (const std::string problem = elf_problem(file); !problem.empty())
    throw LoadError(file.string() + ": not a pinsim plugin: " + problem);
  auto lib = std::make_shared<boost::dll::shared_library>();
  try {
    lib->load(file, boost::dll::load_mode::rtld_now | boost::dll::load_mode::rtld_local);
  } catch (const std::exception& e) {
    throw LoadError(file.string() +
                    ": not a pinsim plugin (cannot be loaded as a shared library: " + e.what() +
                    ")");
  }
  if (!lib->has(PINSIM_ENTRY_SYMBOL))
    throw LoadError(file.string() +
                    ": missing symbol '" PINSIM_ENTRY_SYMBOL
                    "': a shared library, but not a pinsim plugin (use PINSIM_PLUGIN(Class))");
  auto entry = lib->get<const pinsim_plugin*()>(PINSIM_ENTRY_SYMBOL);
  auto table = checked_table(entry(), file.string());
  auto p = std::make_shared<LoadedPlugin>();
  p->library = std::move(lib);
  p->table = table.get();
  p->owner = std::move(table);
  p->path = fs::absolute(file);
  return p;
}

std::shared_ptr<const LoadedPlugin> PluginLoader::remember(std::shared_ptr<const LoadedPlugin> p) {
  auto it = by_name_.find(p->name());
  if (it != by_name_.end()) {
    std::error_code ec;
    if (fs::equivalent(it->second->path, p->path, ec)) return it->second;
    throw LoadError("two plugins named '" + p->name() + "': " + it->second->path.string() +
                    " and " + p->path.string());
  }
  spdlog::debug("loaded plugin '{}' {} from {}", p->name(), p->table->version, p->path.string());
  by_name_.emplace(p->name(), p);
  return p;
}

std::shared_ptr<const LoadedPlugin> PluginLoader::load(const std::string& name) {
  if (auto it = by_name_.find(name); it != by_name_.end()) return it->second;
  // Plugins linked into the program come first (the web build has no other kind).
  if (const StaticPlugin* sp = find_static_plugin(name)) {
    auto p = std::make_shared<LoadedPlugin>();
    auto table = checked_table(sp->entry(), "built-in plugin '" + name + "'");
    p->table = table.get();
    p->owner = std::move(table);
    if (p->name() != name)
      throw LoadError("built-in plugin '" + name + "' declares the name '" + p->name() + "'");
    p->path = static_plugin_path(name);
    spdlog::debug("plugin '{}' {} is built in", name, p->table->version);
    return by_name_.emplace(name, std::move(p)).first->second;
  }
  const std::string file = plugin_file_name(name);
  for (const auto& d : dirs_) {
    std::error_code ec;
    if (fs::is_regular_file(d / file, ec)) return load_path(d / file, name);
  }
  std::string searched;
  for (const auto& d : dirs_) searched += (searched.empty() ? "" : ", ") + d.string();
  throw LoadError("unknown plugin '" + name + "': no " + file + " in " + searched +
                  " (see `pinsim plugins`)");
}

std::shared_ptr<const LoadedPlugin> PluginLoader::load_path(const fs::path& file,
                                                            const std::string& expected_name) {
  auto p = load_plugin_file(file);
  if (!expected_name.empty() && p->name() != expected_name)
    throw LoadError(file.string() + ": declares plugin '" + p->name() + "', expected '" +
                    expected_name + "'");
  return remember(std::move(p));
}

std::vector<PluginLoader::Listing> PluginLoader::list() const {
  std::vector<Listing> out;
  std::set<std::string> seen;
  for (const auto& d : dirs_) {
    std::error_code ec;
    if (!fs::is_directory(d, ec)) continue;
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(d, ec)) {
      const std::string f = e.path().filename().string();
      if (f.rfind("libpinsim_plugin_", 0) == 0 && e.path().extension() == ".so")
        files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      Listing l;
      l.path = f;
      try {
        l.plugin = load_plugin_file(f);
        l.shadowed = !seen.insert(l.plugin->name()).second;
      } catch (const std::exception& e) {
        l.error = e.what();
      }
      out.push_back(std::move(l));
    }
  }
  return out;
}

}  // namespace pinsim
