// pinsim grad SCENE --loss L --wrt PATH... [--out DIR] [--set PATH=VALUE]...
//            [--integrator NAME] [--threads N] [--segment S] [--parameter-derivative M]
#include <spdlog/spdlog.h>

#include <filesystem>
#include <iostream>
#include <memory>

#include "cli_common.hpp"
#include "cli_gradients.hpp"
#include "commands.hpp"
#include "core/format.hpp"
#include "core/input_error.hpp"
#include "core/output_file.hpp"
#include "core/plugin_loader.hpp"

namespace pinsim::cli {
namespace {

struct GradArgs {
  std::string scene;
  std::string loss;
  std::vector<std::string> wrt;
  std::string out;
  std::vector<std::string> set;
  std::string integrator;
  unsigned threads = 0;
  uint64_t segment = 0;
  std::string parameter_derivative = "plugin";
};

int grad_command(const GradArgs& a) {
  Scene scene = load_scene_or_default(a.scene, a.set);
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  grad::GradientOptions opt;
  opt.run.integrator = a.integrator;
  opt.run.threads = a.threads;
  opt.segment = a.segment;
  opt.plugin_parameter_derivatives = a.parameter_derivative == "plugin";
  if (!a.out.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(a.out, ec);
    if (ec) throw OutputError(output_error_text(a.out, "create", ec.value()));
  }
  const grad::GradientReport r =
      grad::scene_gradient(scene, loader, a.wrt, loss_factory(a.loss), opt);
  const nlohmann::json j = r.to_json();
  spdlog::info("{}: loss {} = {} ({} steps; forward {:.3f} s, backward {:.3f} s)", scene.label,
               r.loss_text, num(r.loss, 17), r.steps, r.forward_s, r.backward_s);
  for (const grad::PathGradient& p : r.paths) {
    std::string g;
    for (Eigen::Index c = 0; c < p.gradient.size(); ++c)
      g.append(c ? ", " : "").append(num(p.gradient[c], 17));
    std::cout << p.wrt.path << ": " << g << "\n";
  }
  for (const nlohmann::json& f : j["findings"])
    spdlog::warn(
        "{}: not differentiable at t = {}: {} of particle {}{} (the gradient there is "
        "a one-sided one, or none)",
        scene.label, num(f["t"].get<double>()), f["kind"].get<std::string>(),
        f["particle"].get<int64_t>(),
        f["obstacle"].get<int64_t>() >= 0
            ? " with obstacle " + std::to_string(f["obstacle"].get<int64_t>())
            : std::string());
  if (r.findings_count > r.findings.size())
    spdlog::warn("{}: {} places where the run is not differentiable ({} listed in gradient.json)",
                 scene.label, r.findings_count, r.findings.size());
  if (!a.out.empty()) {
    write_file_atomically(std::filesystem::path(a.out) / "gradient.json", j.dump(2) + "\n");
    spdlog::info("gradient written to {}",
                 (std::filesystem::path(a.out) / "gradient.json").string());
  }
  return 0;
}

}  // namespace

void add_grad_command(CLI::App& app) {
  auto a = std::make_shared<GradArgs>();
  CLI::App* c = app.add_subcommand(
      "grad", "Gradient of a loss of a run in scene values, by the adjoint of the run");
  c->add_option("scene", a->scene, "Scene file (JSON)")->required();
  c->add_option("--loss", a->loss,
                "final:I:x|y|vx|vy (a final coordinate of particle I), target:I:X,Y[@T] "
                "(squared distance of particle I to (X, Y) at time T, default the end) or "
                "misfit:RUN_FOLDER (sum over its frames of squared position differences)")
      ->required();
  c->add_option("--wrt", a->wrt,
                "Values to differentiate in, as --set paths: particles[I].x, particles[I].v, "
                "bodies[K].center|origin|root, bodies[K].velocity, forces[K].params.NAME, "
                "obstacles[K].material.restitution|friction|kick (sdf)")
      ->required()
      ->take_all();
  c->add_option("--out,-o", a->out, "Folder for gradient.json");
  c->add_option("--set", a->set, "Override a scene value, e.g. --set time.dt=0.0005")->take_all();
  c->add_option("--integrator", a->integrator,
                "Use this integrator instead of the scene's (symplectic_euler, "
                "velocity_verlet, implicit_euler)");
  c->add_option("--threads", a->threads, "Threads, as for pinsim run")
      ->check(CLI::Range(1u, kMaxThreads));
  c->add_option("--segment", a->segment,
                "Steps between checkpoints (default: the square root of the steps)");
  c->add_option("--parameter-derivative", a->parameter_derivative,
                "plugin: a force's derivative in a parameter from its plugin where it gives "
                "it, else central differences of the plugin (default); differences: always "
                "the differences (to cross-check a plugin's)")
      ->check(CLI::IsMember({"plugin", "differences"}));
  c->callback([a] { throw CLI::RuntimeError(grad_command(*a)); });
}

}  // namespace pinsim::cli
