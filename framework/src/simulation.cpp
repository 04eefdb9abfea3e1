#include "simulation.hpp"

#include <spdlog/spdlog.h>

#include <cmath>

#include "integrator.hpp"
#include "param_validation.hpp"

namespace pinsim {
namespace {

std::shared_ptr<const LoadedPlugin> load_ref(PluginLoader& loader, const PluginRef& ref,
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

void emit_event(void* ctx, const pinsim_event* e) {
  static_cast<std::vector<pinsim_event>*>(ctx)->push_back(*e);
}

}  // namespace

Simulation::Simulation(const Scene& scene, PluginLoader& loader, const RunOptions& options)
    : scene_(scene), state_(scene.initial_state()) {
  integrator_name_ = options.integrator.empty() ? scene_.integrator : options.integrator;
  try {
    integrator_ = make_integrator(integrator_name_);
  } catch (const std::invalid_argument& e) {
    throw SceneError(scene_.label + ": integrator: " + e.what());
  }

  PluginRef bref = scene_.backend;
  if (!options.backend.empty() && options.backend != bref.name) {
    // Another backend's parameters do not apply; it starts from its defaults.
    bref = PluginRef{options.backend, "", nlohmann::json::object(), "--backend " + options.backend};
  }
  auto bplugin = load_ref(loader, bref, scene_.base_dir);
  if (bplugin->table->kind != PINSIM_KIND_BACKEND)
    throw SceneError(bref.where + ": plugin '" + bref.name + "' is a force, not a backend");

  for (const auto& f : scene_.forces) {
    auto p = load_ref(loader, f, scene_.base_dir);
    if (p->table->kind != PINSIM_KIND_FORCE)
      throw SceneError(f.where + ".type: plugin '" + f.name + "' is a backend, not a force");
    InstanceArgs a;
    a.params = validate_params(*p->table, f.params, f.where + ".params");
    a.elements = scene_.resolve_elements(f, p->table->arity == 0 ? 1 : p->table->arity);
    a.context = f.where;
    forces_.push_back(std::make_unique<ForceInstance>(p, state_, std::move(a)));
  }

  InstanceArgs ba;
  ba.params = validate_params(*bplugin->table, bref.params, bref.where + ".params");
  ba.scene = scene_.backend_scene;
  ba.context = scene_.label;
  backend_ = std::make_unique<BackendInstance>(bplugin, state_, std::move(ba));

  e0_ = kinetic_energy(state_) + potential_energy(state_);
  // Energy scale for relative drift: total |terms| at the start, never zero.
  e_scale_ = kinetic_energy(state_);
  for (const auto& f : forces_)
    if (f->has_energy()) e_scale_ += std::abs(f->energy(state_.view()));
  if (!(e_scale_ > 0.0)) e_scale_ = 1.0;
}

Simulation::~Simulation() = default;

void Simulation::compute_forces(const State& s, Eigen::Matrix2Xd& f) {
  f.setZero(2, s.x.cols());
  const pinsim_state_view view = s.view();
  for (const auto& force : forces_) force->add_force(view, f.data());
  ++force_evals_;
  check_finite_forces(s, f);
}

void Simulation::check_finite_forces(const State& s, const Eigen::Matrix2Xd& f) const {
  if (f.allFinite()) return;
  // Find the first particle and the first plugin that produced a non-finite force.
  const pinsim_state_view view = s.view();
  Eigen::Matrix2Xd one(2, s.x.cols());
  for (const auto& force : forces_) {
    one.setZero();
    force->add_force(view, one.data());
    for (Eigen::Index i = 0; i < one.cols(); ++i)
      if (!one.col(i).allFinite())
        throw NumericError("non-finite force (" + std::to_string(one(0, i)) + ", " +
                               std::to_string(one(1, i)) + ") on particle " + std::to_string(i) +
                               " from " + force->context() + " (plugin '" + force->plugin().name() +
                               "')",
                           step_ + 1, s.t, i);
  }
  for (Eigen::Index i = 0; i < f.cols(); ++i)
    if (!f.col(i).allFinite())
      throw NumericError("non-finite total force on particle " + std::to_string(i), step_ + 1, s.t,
                         i);
}

void Simulation::drift(State& s, double dt) {
  const pinsim_event_sink sink{&events_, &emit_event};
  backend_->advance(s, dt, &sink);
}

void Simulation::check_finite_state() const {
  const auto& s = state_;
  for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
    if (!s.x.col(i).allFinite() || !s.v.col(i).allFinite())
      throw NumericError("non-finite state of particle " + std::to_string(i) + ": x = (" +
                             std::to_string(s.x(0, i)) + ", " + std::to_string(s.x(1, i)) +
                             "), v = (" + std::to_string(s.v(0, i)) + ", " +
                             std::to_string(s.v(1, i)) + ") after backend '" +
                             backend_->plugin().name() + "'",
                         step_ + 1, s.t, i);
  }
}

double Simulation::kinetic_energy(const State& s) const {
  double e = 0.0;
  for (Eigen::Index i = 0; i < s.x.cols(); ++i)
    if (s.inv_mass[i] > 0.0) e += 0.5 * s.v.col(i).squaredNorm() / s.inv_mass[i];
  return e;
}

double Simulation::potential_energy(const State& s) const {
  double e = 0.0;
  const pinsim_state_view view = s.view();
  for (const auto& f : forces_)
    if (f->has_energy()) e += f->energy(view);
  return e;
}

bool Simulation::energy_complete() const {
  for (const auto& f : forces_)
    if (!f->has_energy()) return false;
  return true;
}

void Simulation::check_energy() {
  const double e = kinetic_energy(state_) + potential_energy(state_);
  const double drift = std::abs(e - e0_) / e_scale_;
  if (drift > max_drift_) max_drift_ = drift;
  if (e - e0_ > scene_.energy_blowup * e_scale_) {
    // Blame the particle with the largest kinetic energy.
    Eigen::Index worst = 0;
    double worst_ke = -1.0;
    for (Eigen::Index i = 0; i < state_.x.cols(); ++i) {
      const double ke =
          state_.inv_mass[i] > 0.0 ? 0.5 * state_.v.col(i).squaredNorm() / state_.inv_mass[i] : 0.0;
      if (ke > worst_ke) {
        worst_ke = ke;
        worst = i;
      }
    }
    throw NumericError(
        "energy blow-up: E = " + std::to_string(e) + " from E0 = " + std::to_string(e0_) +
            " (growth " + std::to_string(drift) +
            " x the initial energy scale, limit checks.energy_blowup = " +
            std::to_string(scene_.energy_blowup) + "); fastest particle " + std::to_string(worst),
        step_, state_.t, worst);
  }
}

void Simulation::step() {
  // Time at the end of the step from the step count, so t carries no accumulated rounding.
  const double t_end = static_cast<double>(step_ + 1) * scene_.dt;
  integrator_->step(*this, scene_.dt);
  check_finite_state();
  state_.t = t_end;
  ++step_;
  if (step_ % scene_.energy_every == 0) check_energy();
}

}  // namespace pinsim
