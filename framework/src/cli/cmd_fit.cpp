// pinsim fit SCENE (--target RUN | --loss LOSS) --wrt PATH... [--out DIR] [--set PATH=VALUE]...
//            [--max-iterations N] [--tolerance T]
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
#include "gradients/fit.hpp"

namespace pinsim::cli {
namespace {

struct FitArgs {
  std::string scene;
  std::string target;
  std::string loss;  ///< in place of --target: a loss of `pinsim grad` to minimize
  std::vector<std::string> wrt;
  std::string out;
  std::vector<std::string> set;
  int max_iterations = 100;
  double tolerance = 1e-10;
};

/// The --set assignments of the fitted values x (the components of `values` in order).
std::vector<std::string> assignments(const std::vector<grad::WrtValue>& values,
                                     const Eigen::VectorXd& x) {
  std::vector<std::string> out;
  Eigen::Index k = 0;
  for (const grad::WrtValue& v : values) {
    std::vector<double> c;
    for (std::size_t j = 0; j < v.value.size(); ++j) c.push_back(x[k++]);
    out.push_back(assignment(v.path, c));
  }
  return out;
}

int fit_command(const FitArgs& a) {
  if (a.target.empty() == a.loss.empty())
    throw InputError(
        "pinsim fit: give either --target RUN_DIR (the misfit to a recorded run) "
        "or --loss LOSS, not " +
        std::string(a.target.empty() ? "neither" : "both"));
  const std::string what = a.target.empty() ? "loss" : "misfit";
  const Scene start = load_scene_or_default(a.scene, a.set);
  PluginLoader loader(plugin_search_dirs(start.plugin_path));
  // the values and their bounds, as the scene and its plugins give them
  std::vector<grad::WrtValue> values;
  {
    const Simulation sim(start, loader);
    values = grad::resolve_wrt(start, sim, a.wrt);
  }
  std::vector<grad::FitVariable> vars;
  for (const grad::WrtValue& v : values)
    for (std::size_t c = 0; c < v.value.size(); ++c) {
      grad::FitVariable f;
      f.name = v.path + (v.value.size() > 1 ? "[" + std::to_string(c) + "]" : "");
      f.start = v.value[c];
      f.lower = v.lower;
      f.upper = v.upper;
      vars.push_back(f);
    }
  const grad::LossFactory loss = loss_factory(a.target.empty() ? a.loss : "misfit:" + a.target);
  grad::FitObjective objective = [&](const Eigen::VectorXd& x, Eigen::VectorXd& g) {
    std::vector<std::string> overrides = a.set;
    for (const std::string& s : assignments(values, x)) overrides.push_back(s);
    const Scene scene = load_scene_or_default(a.scene, overrides);
    const grad::GradientReport r = grad::scene_gradient(scene, loader, a.wrt, loss);
    Eigen::Index k = 0;
    for (const grad::PathGradient& p : r.paths)
      for (Eigen::Index c = 0; c < p.gradient.size(); ++c) g[k++] = p.gradient[c];
    return r.loss;
  };
  nlohmann::json iterations = nlohmann::json::array();
  auto on_iteration = [&](const grad::FitIteration& it) {
    std::string line = "iteration " + std::to_string(it.iteration) + " (" +
                       std::to_string(it.evaluations) + " runs): " + what + " " + num(it.loss, 12);
    nlohmann::json xs = nlohmann::json::object();
    for (std::size_t k = 0; k < vars.size(); ++k) {
      const auto i = static_cast<Eigen::Index>(k);
      line += ", " + vars[k].name + " = " + num(it.x[i], 12);
      xs[vars[k].name] = {{"value", it.x[i]}, {"gradient", it.g[i]}};
    }
    std::cout << line << std::endl;
    iterations.push_back({{"iteration", it.iteration},
                          {"evaluations", it.evaluations},
                          {"misfit", it.loss},
                          {"values", xs}});
  };
  grad::FitOptions opt;
  opt.max_iterations = a.max_iterations;
  opt.gradient_tolerance = a.tolerance;
  grad::FitResult res;
  try {
    res = grad::fit_lbfgsb(vars, objective, opt, on_iteration);
  } catch (const std::invalid_argument& e) {
    throw InputError(e.what());
  }
  std::vector<std::string> overrides = a.set;
  for (const std::string& s : assignments(values, res.x)) overrides.push_back(s);
  const Scene fitted = load_scene_or_default(a.scene, overrides);
  std::cout << "fitted (" << res.iterations << " iterations, " << res.evaluations
            << " runs; stopped by " << res.stop << "): " << what << " " << num(res.loss, 12)
            << "\n";
  nlohmann::json result = nlohmann::json::object();
  for (std::size_t k = 0; k < vars.size(); ++k) {
    std::cout << "  " << vars[k].name << " = " << num(res.x[static_cast<Eigen::Index>(k)], 17)
              << "\n";
    result[vars[k].name] = res.x[static_cast<Eigen::Index>(k)];
  }
  if (!a.out.empty()) {
    const std::filesystem::path out = a.out;
    std::error_code ec;
    std::filesystem::create_directories(out, ec);
    if (ec) throw OutputError(output_error_text(out, "create", ec.value()));
    write_file_atomically(out / "scene.json", fitted.doc.dump(2) + "\n");
    const nlohmann::json report = {{"target", a.target.empty() ? a.loss : a.target},
                                   {"scene", fitted.label},
                                   {"values", result},
                                   {"misfit", res.loss},
                                   {"iterations", res.iterations},
                                   {"evaluations", res.evaluations},
                                   {"stop", res.stop},
                                   {"history", iterations}};
    write_file_atomically(out / "fit.json", report.dump(2) + "\n");
    spdlog::info("fitted scene written to {}", (out / "scene.json").string());
  }
  return 0;
}

}  // namespace

void add_fit_command(CLI::App& app) {
  auto a = std::make_shared<FitArgs>();
  CLI::App* c = app.add_subcommand(
      "fit", "Fit scene values to a recorded run: least squares on the misfit by L-BFGS-B");
  c->add_option("scene", a->scene, "Scene file (JSON)")->required();
  c->add_option("--target", a->target,
                "Run folder to fit (pinsim run --out): the misfit is the sum over its frames of "
                "squared position differences");
  c->add_option("--loss", a->loss,
                "In place of --target: a loss of pinsim grad to minimize (target:I:X,Y[@T], "
                "final:I:x|y|vx|vy, misfit:RUN_DIR)");
  c->add_option("--wrt", a->wrt,
                "Values to fit, as --set paths (particles[I].x, particles[I].v, "
                "bodies[K].center|origin|root, bodies[K].velocity, forces[K].params.NAME, "
                "obstacles[K].material.restitution|friction|kick); bounds "
                "from the plugins' parameter tables and the materials' ranges")
      ->required()
      ->take_all();
  c->add_option("--out,-o", a->out, "Folder for the fitted scene.json and fit.json");
  c->add_option("--set", a->set, "Override a scene value (the start of the fit)")->take_all();
  c->add_option("--max-iterations", a->max_iterations, "Iteration limit")
      ->check(CLI::Range(1, 100000));
  c->add_option("--tolerance", a->tolerance,
                "Stop when the projected gradient falls to this fraction of its start")
      ->check(CLI::PositiveNumber);
  c->callback([a] { throw CLI::RuntimeError(fit_command(*a)); });
}

}  // namespace pinsim::cli
