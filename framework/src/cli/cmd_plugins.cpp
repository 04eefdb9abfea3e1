// pinsim plugins [NAME]: list the plugins found, or print one plugin's parameter table.
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "core/param_validation.hpp"
#include "core/plugin_loader.hpp"

namespace pinsim::cli {

void add_plugins_command(CLI::App& app) {
  auto name = std::make_shared<std::string>();
  auto path = std::make_shared<std::vector<std::string>>();
  CLI::App* c = app.add_subcommand("plugins", "List plugins, or show one plugin's parameters");
  c->add_option("name", *name, "Plugin name or library path");
  c->add_option("--plugin-path", *path,
                "folder searched first (repeat); then $PINSIM_PLUGIN_PATH, the install and "
                "the build tree, as for check-plugin and run");
  c->callback([name, path] {
    PluginLoader loader(
        plugin_search_dirs(std::vector<std::filesystem::path>(path->begin(), path->end())));
    if (!name->empty()) {
      const bool is_path = name->find('/') != std::string::npos;
      auto p = is_path ? loader.load_path(*name, "") : loader.load(*name);
      std::cout << format_param_table(*p->table) << "  library: " << p->path.string() << "\n";
      return;
    }
    std::cout << "search path:";
    for (const auto& d : loader.dirs()) std::cout << " " << d.string();
    std::cout << "\n";
    for (const auto& l : loader.list()) {
      if (!l.plugin) {
        // (the error names the file; skipped, the listing goes on)
        std::cout << "  (broken)  " << l.error << "\n";
        continue;
      }
      const auto* t = l.plugin->table;
      std::cout << "  " << (t->kind == PINSIM_KIND_FORCE ? "force   " : "backend ") << t->name
                << " " << t->version << (l.shadowed ? "  (shadowed by an earlier one)" : "")
                << "\n      " << t->doc << "\n      " << l.path.string() << "\n";
    }
  });
}

}  // namespace pinsim::cli
