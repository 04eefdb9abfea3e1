// The one factory for plugin instances: a scene's reference to a force or backend plugin ->
// the library loaded, its kind checked, its parameters validated, the instance created.
#pragma once

#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>

#include "core/plugin_instance.hpp"
#include "core/plugin_loader.hpp"
#include "core/scene.hpp"

namespace pinsim {

/// The library `ref` names: its `library` path (relative to `base_dir`) or, without one, the
/// plugin found by name. Throws LoadError prefixed with `ref.where`.
std::shared_ptr<const LoadedPlugin> load_plugin(PluginLoader& loader, const PluginRef& ref,
                                                const std::filesystem::path& base_dir);

/// An instance of the backend `ref` names (the scene's, or one chosen on the command line)
/// for `scene`, seeing the obstacle description `backend_scene` and starting from `initial`.
/// Throws LoadError, or SceneError if the plugin is a force or a parameter is wrong.
std::unique_ptr<BackendInstance> create_backend(const Scene& scene, PluginLoader& loader,
                                                const PluginRef& ref,
                                                const nlohmann::json& backend_scene,
                                                const State& initial);

/// An instance of the force `f` of `scene` over its resolved elements, starting from
/// `initial`. Throws LoadError, or SceneError if the plugin is a backend or a parameter or
/// element is wrong.
std::unique_ptr<ForceInstance> create_force(const Scene& scene, PluginLoader& loader,
                                            const ForceSpec& f, const State& initial);

}  // namespace pinsim
