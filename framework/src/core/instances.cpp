#include "core/instances.hpp"

#include "core/input_error.hpp"
#include "core/param_validation.hpp"

namespace pinsim {

std::shared_ptr<const LoadedPlugin> load_plugin(PluginLoader& loader, const PluginRef& ref,
                                                const std::filesystem::path& base_dir) {
  try {
    if (!ref.library.empty()) {
      std::filesystem::path lib = ref.library;
      if (lib.is_relative()) lib = base_dir / lib;
      return loader.load_path(lib, ref.name);
    }
    return loader.load(ref.name);
  } catch (const LoadError& e) {
    throw LoadError(ref.where + ": " + e.what());
  }
}

std::unique_ptr<BackendInstance> create_backend(const Scene& scene, PluginLoader& loader,
                                                const PluginRef& ref,
                                                const nlohmann::json& backend_scene,
                                                const State& initial) {
  auto p = load_plugin(loader, ref, scene.base_dir);
  if (p->table->kind != PINSIM_KIND_BACKEND)
    throw SceneError(ref.where + ": plugin '" + ref.name + "' is a force, not a backend");
  InstanceArgs a;
  a.params = validate_params(*p->table, ref.params, ref.where + ".params");
  a.scene = backend_scene;
  a.context = scene.label;
  return std::make_unique<BackendInstance>(p, initial, std::move(a));
}

std::unique_ptr<ForceInstance> create_force(const Scene& scene, PluginLoader& loader,
                                            const ForceSpec& f, const State& initial) {
  auto p = load_plugin(loader, f, scene.base_dir);
  if (p->table->kind != PINSIM_KIND_FORCE)
    throw SceneError(f.where + ".type: plugin '" + f.name + "' is a backend, not a force");
  InstanceArgs a;
  a.params = validate_params(*p->table, f.params, f.where + ".params");
  a.elements = scene.resolve_elements(f, p->table->arity);
  a.context = f.where;
  return std::make_unique<ForceInstance>(p, initial, std::move(a));
}

}  // namespace pinsim
