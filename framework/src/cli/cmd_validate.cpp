// pinsim validate SCENE [--set ...]: parse, load the named plugins, check every parameter
// and create every instance, without stepping.
#include <iostream>
#include <memory>

#include "cli_common.hpp"
#include "commands.hpp"
#include "core/simulation.hpp"

namespace pinsim::cli {

void add_validate_command(CLI::App& app) {
  struct Args {
    std::string scene;
    std::vector<std::string> set;
  };
  auto a = std::make_shared<Args>();
  CLI::App* c = app.add_subcommand("validate", "Check a scene without running it");
  c->add_option("scene", a->scene, "Scene file (JSON)")->required();
  c->add_option("--set", a->set, "Override a scene value, e.g. --set time.dt=0.0005")->take_all();
  c->callback([a] {
    Scene scene = load_scene(a->scene, a->set);
    PluginLoader loader(plugin_search_dirs(scene.plugin_path));
    Simulation sim(scene, loader);
    std::cout << scene.label << ": ok: " << scene.particles.size() << " particles, "
              << scene.bodies.size() << " bodies, " << scene.forces.size() << " forces, backend '"
              << sim.backend().plugin().name() << "', integrator '" << sim.integrator_name()
              << "', " << scene.steps() << " steps of dt = " << scene.dt << " s\n";
  });
}

}  // namespace pinsim::cli
