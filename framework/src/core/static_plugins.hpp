// The static plugin registry: plugins linked into the program instead of loaded from a
// shared library (the web build; native builds with PINSIM_STATIC_PLUGINS=ON). Each one is
// the same C table a library's pinsim_plugin_entry returns, under its own entry function
// (pinsim_static_entry_<name>, see PINSIM_STATIC_ENTRY in pinsim/plugin.hpp). PluginLoader
// consults this registry before it searches the plugin path.
#pragma once

#include <pinsim/abi.h>

#include <filesystem>
#include <string>
#include <vector>

namespace pinsim {

struct StaticPlugin {
  std::string name;
  const pinsim_plugin* (*entry)();
};

/// Adds a plugin to the registry (the generated static_plugin_table.cpp does, at start-up).
/// A second registration of the same name replaces nothing and returns false.
bool register_static_plugin(const std::string& name, const pinsim_plugin* (*entry)());

/// Every registered plugin, in registration order.
const std::vector<StaticPlugin>& static_plugins();

/// The registered plugin called `name`, or null.
const StaticPlugin* find_static_plugin(const std::string& name);

/// What LoadedPlugin::path holds for a built-in plugin: "(built in)/<name>".
std::filesystem::path static_plugin_path(const std::string& name);

}  // namespace pinsim
