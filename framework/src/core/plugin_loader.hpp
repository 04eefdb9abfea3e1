// Loading plugin libraries through Boost.DLL and checking their tables.
#pragma once

#include <pinsim/abi.h>

#include <boost/dll/shared_library.hpp>
#include <filesystem>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace pinsim {

/// Any failure to find or load a plugin; the message names the plugin and the file.
class LoadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A loaded library and its checked table. Instances hold a shared_ptr to this, so the
/// library stays mapped while any instance lives.
struct LoadedPlugin {
  std::shared_ptr<boost::dll::shared_library> library;
  /// The table as the host reads it: a whole table of this ABI, with every entry the
  /// plugin's own table does not hold (an older minor's) absent.
  const pinsim_plugin* table = nullptr;
  std::filesystem::path path;
  /// Keeps `table` alive: the host's copy of a loaded table, or whatever owns a table that
  /// does not come from a library (the grader's proxy for a sandboxed submission).
  std::shared_ptr<const void> owner;
  std::string name() const { return table->name; }
  bool is_force() const { return table->kind == PINSIM_KIND_FORCE; }
};

/// The file name a plugin called `name` has: libpinsim_plugin_<name>.so
std::string plugin_file_name(const std::string& name);

/// Directories searched, in order: the scene's plugin_path entries, $PINSIM_PLUGIN_PATH
/// (colon separated), the build tree's plugin folder, the install prefix's plugin folder.
std::vector<std::filesystem::path> plugin_search_dirs(
    const std::vector<std::filesystem::path>& scene_paths = {});

/// Loads one library file and checks it is a pinsim plugin of a compatible ABI.
std::shared_ptr<const LoadedPlugin> load_plugin_file(const std::filesystem::path& file);

class PluginLoader {
 public:
  explicit PluginLoader(std::vector<std::filesystem::path> dirs) : dirs_(std::move(dirs)) {}

  /// Finds `name` in the search directories (first match wins) and loads it.
  std::shared_ptr<const LoadedPlugin> load(const std::string& name);
  /// Makes load(plugin->name()) return `plugin` (a table that is not a file here, such as
  /// the grader's proxy for a sandboxed submission).
  void provide(std::shared_ptr<const LoadedPlugin> plugin) {
    by_name_[plugin->name()] = std::move(plugin);
  }
  /// Loads an explicit library file; `expected_name` may be empty.
  std::shared_ptr<const LoadedPlugin> load_path(const std::filesystem::path& file,
                                                const std::string& expected_name);

  struct Listing {
    std::filesystem::path path;
    std::shared_ptr<const LoadedPlugin> plugin;  ///< null when loading failed
    std::string error;                           ///< why loading failed
    bool shadowed = false;                       ///< an earlier directory has the same name
  };
  /// Every libpinsim_plugin_*.so in the search directories, loaded for their tables.
  std::vector<Listing> list() const;

  const std::vector<std::filesystem::path>& dirs() const { return dirs_; }
  /// Names of the plugins loaded so far (a run loads only those its scene names).
  std::vector<std::string> loaded() const {
    std::vector<std::string> out;
    for (const auto& [name, _] : by_name_) out.push_back(name);
    return out;
  }

 private:
  std::shared_ptr<const LoadedPlugin> remember(std::shared_ptr<const LoadedPlugin> p);

  std::vector<std::filesystem::path> dirs_;
  std::map<std::string, std::shared_ptr<const LoadedPlugin>> by_name_;
};

}  // namespace pinsim
