#include "core/static_plugins.hpp"

namespace pinsim {
namespace {
std::vector<StaticPlugin>& registry() {
  static std::vector<StaticPlugin> r;  // constructed on first use: safe from static initialisers
  return r;
}
}  // namespace

bool register_static_plugin(const std::string& name, const pinsim_plugin* (*entry)()) {
  if (entry == nullptr || find_static_plugin(name) != nullptr) return false;
  registry().push_back({name, entry});
  return true;
}

const std::vector<StaticPlugin>& static_plugins() { return registry(); }

const StaticPlugin* find_static_plugin(const std::string& name) {
  for (const auto& p : registry())
    if (p.name == name) return &p;
  return nullptr;
}

std::filesystem::path static_plugin_path(const std::string& name) { return "(built in)/" + name; }

}  // namespace pinsim
