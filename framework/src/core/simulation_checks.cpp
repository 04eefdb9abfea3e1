// Simulation's numeric checks: where a failure began, and which plugin is involved.
#include <cmath>

#include "core/format.hpp"
#include "core/simulation.hpp"

namespace pinsim {
namespace {

std::string pair(double a, double b) { return "(" + num(a) + ", " + num(b) + ")"; }
std::string pair(const Eigen::Vector2d& p) { return pair(p[0], p[1]); }

}  // namespace

std::string Simulation::force_label(std::size_t k) const {
  return "forces[" + std::to_string(k) + "] '" + forces_[k]->plugin().name() + "'";
}

int64_t Simulation::strongest_force(const State& s, Eigen::Index i, double& mag) const {
  const pinsim_state_view view = s.view();
  Eigen::Matrix2Xd one(2, s.x.cols());
  int64_t best = -1;
  mag = 0.0;
  for (std::size_t k = 0; k < forces_.size(); ++k) {
    one.setZero();
    forces_[k]->add_force(view, one.data());
    const double m = one.col(i).norm();
    if (std::isnan(m) || m > mag) {
      mag = m;
      best = static_cast<int64_t>(k);
    }
    if (std::isnan(m)) break;  // nothing weighs more
  }
  return best;
}

std::string Simulation::strongest_force_text(const State& s, Eigen::Index i,
                                             std::string& plugin) const {
  double mag = 0.0;
  const int64_t k = strongest_force(s, i, mag);
  if (k < 0) {
    plugin = "integrator '" + integrator_name_ + "'";
    return "; no force acts on it";
  }
  plugin = force_label(static_cast<std::size_t>(k));
  return "; largest force on it: " + plugin + " (|f| = " + num(mag) + ")";
}

void Simulation::check_finite_forces(const State& s, const Eigen::Matrix2Xd& f) const {
  if (f.allFinite()) return;
  // Find the first plugin and the first particle it gave a non-finite force, a free one if
  // any (a spring from a pinned end to a runaway particle is non-finite at both ends).
  const pinsim_state_view view = s.view();
  Eigen::Matrix2Xd one(2, s.x.cols());
  for (std::size_t k = 0; k < forces_.size(); ++k) {
    one.setZero();
    forces_[k]->add_force(view, one.data());
    Eigen::Index i = -1;
    for (Eigen::Index j = 0; j < one.cols(); ++j)
      if (!one.col(j).allFinite() && (i < 0 || (s.inv_mass[i] == 0.0 && s.inv_mass[j] > 0.0)))
        i = j;
    if (i < 0) continue;
    throw NumericError(NumericError::Kind::NonFinite,
                       "non-finite force " + pair(one(0, i), one(1, i)) + " on particle " +
                           std::to_string(i) + " from " + force_label(k) +
                           " at x = " + pair(s.x.col(i)) + ", v = " + pair(s.v.col(i)),
                       step_ + 1, s.t, i, force_label(k));
  }
  for (Eigen::Index i = 0; i < f.cols(); ++i)
    if (!f.col(i).allFinite())
      throw NumericError(NumericError::Kind::NonFinite,
                         "non-finite total force " + pair(f(0, i), f(1, i)) + " on particle " +
                             std::to_string(i) +
                             " (each force alone is finite: their sum overflows)",
                         step_ + 1, s.t, i);
}

void Simulation::throw_step_finding(const StepFinding& found, double t_end) const {
  const State& s = state_;
  const Eigen::Index i = found.particle;
  const std::string who = "particle " + std::to_string(i);
  std::string plugin;
  if (found.what == StepFinding::What::NonFinite) {
    const std::string state = "x = " + pair(s.x.col(i)) + ", v = " + pair(s.v.col(i));
    std::string text;
    if (found.phase == StepFinding::Phase::Drift) {
      plugin = "backend '" + backend_->plugin().name() + "'";
      text = "non-finite state of " + who + " after the drift by " + plugin + ": " + state +
             "; it entered the drift finite, at v = " + pair(found.v_in);
    } else {
      // Every force was finite (checked), so a kick overflowed: name the largest force on
      // the particle in the state the step ended in.
      text = "non-finite velocity of " + who + " after a force kick " +
             (found.phase == StepFinding::Phase::BeforeDrift ? "before" : "after") +
             " the drift: " + state;
      text += strongest_force_text(s, i, plugin);
    }
    throw NumericError(NumericError::Kind::NonFinite, text, step_ + 1, t_end, i, plugin);
  }
  const std::string forces = strongest_force_text(s, i, plugin);
  throw NumericError(NumericError::Kind::EnergyBlowup,
                     "energy blow-up: the kinetic energy of " + who + " grew from " +
                         num(found.k_prev) + " to " + num(found.k_free) + " in one step, past " +
                         num(scene_.kinetic_growth) + " x (its energy + the energy scale " +
                         num(found.scale) +
                         ") (checks.kinetic_growth = " + num(scene_.kinetic_growth) + ")" + forces,
                     step_ + 1, t_end, i, plugin);
}

void Simulation::check_energy() {
  const double e = kinetic_energy(state_) + potential_energy(state_);
  const double drift = std::abs(e - e0_) / e_scale_;
  if (drift > max_drift_) max_drift_ = drift;
  const bool blown = !(e - e0_ <= scene_.energy_blowup * e_scale_);  // a NaN energy too
  // Blame the particle whose kinetic energy grew most since the last check.
  Eigen::Index worst = -1;
  double most = 0.0;
  for (Eigen::Index i = 0; i < state_.x.cols(); ++i) {
    const double w = state_.inv_mass[i];
    const double ke = w > 0.0 ? 0.5 * state_.v.col(i).squaredNorm() / w : 0.0;
    if (blown && (worst < 0 || ke - k_at_check_[i] > most)) {
      most = ke - k_at_check_[i];
      worst = i;
    }
    k_at_check_[i] = ke;
  }
  if (!blown) return;
  std::string plugin, forces;
  if (worst >= 0) forces = strongest_force_text(state_, worst, plugin);
  throw NumericError(
      NumericError::Kind::EnergyBlowup,
      "energy blow-up: E = " + num(e) + " from E0 = " + num(e0_) + " (growth " + num(drift) +
          " x the initial energy scale " + num(e_scale_) + ", limit checks.energy_blowup = " +
          num(scene_.energy_blowup) + "); particle " + std::to_string(worst) +
          " gained the most kinetic energy since the last check (" + num(most) + ")" + forces,
      step_, state_.t, worst, plugin);
}

}  // namespace pinsim
