#include "core/integrator.hpp"

#include <functional>
#include <map>
#include <stdexcept>

#include "core/integrator_kinds.hpp"
#include "core/simulation.hpp"

namespace pinsim {
namespace {

/// v += h M^-1 f, per particle (pinned particles have inv_mass 0 and keep their velocity).
void kick(State& s, const Eigen::Matrix2Xd& f, double h) {
  for (Eigen::Index i = 0; i < s.x.cols(); ++i) s.v.col(i) += (h * s.inv_mass[i]) * f.col(i);
}

/// Symplectic (semi-implicit) Euler, kick then drift:
///   v_{n+1} = v_n + h M^-1 f(x_n, v_n);  x_{n+1} = x_n + h v_{n+1} (by the backend).
/// For constant gravity y_N = y_0 + v_0 T - g T^2/2 - g h T/2: first order, error -g h T/2.
class SymplecticEuler : public Integrator {
 public:
  void step(Simulation& sim, double h) override {
    State& s = sim.state();
    sim.compute_forces(s, f_);
    kick(s, f_, h);
    sim.drift(s, h);
  }

 private:
  Eigen::Matrix2Xd f_;
};

/// Velocity Verlet, kick/2 - drift - kick/2:
///   v_{n+1/2} = v_n + h/2 M^-1 f(x_n);  x_{n+1} = x_n + h v_{n+1/2};
///   v_{n+1} = v_{n+1/2} + h/2 M^-1 f(x_{n+1}).
/// Second order; exact (to rounding) for constant forces. A contact inside the drift
/// reflects v_{n+1/2}, not the velocity at the time of impact v_n + tau M^-1 f_n;
/// correct_impacts fixes the impulse so a bounce keeps the method second order.
/// Velocity-dependent forces (damping): the closing half kick needs f(x_{n+1}, v_{n+1}), and
/// f(x_{n+1}, v_{n+1/2}) is off by O(h), which leaves the method first order. One predictor
///   v* = v_{n+1/2} + h/2 M^-1 f(x_{n+1}, v_{n+1/2}),  v_{n+1} = v_{n+1/2} + h/2 M^-1 f(x_{n+1},
///   v*)
/// makes the force error O(h^2) and restores second order, at one more force evaluation per
/// step, spent only when a force is dissipative (or declares no energy, so may depend on v).
class VelocityVerlet : public Integrator {
 public:
  void step(Simulation& sim, double h) override {
    if (!checked_) {
      checked_ = true;
      for (const auto& f : sim.forces()) {
        const uint32_t caps = f->plugin().table->capabilities;
        velocity_dependent_ = velocity_dependent_ || (caps & PINSIM_CAP_DISSIPATIVE) != 0 ||
                              (caps & PINSIM_CAP_ENERGY) == 0;
      }
    }
    State& s = sim.state();
    sim.compute_forces(s, f_);
    kick(s, f_, 0.5 * h);
    const std::size_t first_event = sim.events().size();
    sim.drift(s, h);
    if (sim.events().size() > first_event) {
      accelerations(s, f_, a_);
      correct_impacts(s, sim.events(), first_event, s.t, 0.5 * h, a_);
    }
    sim.compute_forces(s, f_);
    if (velocity_dependent_) {
      predicted_ = s;
      kick(predicted_, f_, 0.5 * h);
      sim.compute_forces(predicted_, f_);
    }
    kick(s, f_, 0.5 * h);
  }

 private:
  Eigen::Matrix2Xd f_, a_;
  State predicted_;
  bool checked_ = false, velocity_dependent_ = false;
};

const std::map<std::string, std::function<std::unique_ptr<Integrator>()>>& registry() {
  static const std::map<std::string, std::function<std::unique_ptr<Integrator>()>> r = {
      {"symplectic_euler", [] { return std::make_unique<SymplecticEuler>(); }},
      {"velocity_verlet", [] { return std::make_unique<VelocityVerlet>(); }},
      {"explicit_euler", [] { return make_explicit_euler(); }},
      {"rk4", [] { return make_rk4(); }},
      {"implicit_euler", [] { return make_implicit_euler(); }},
  };
  return r;
}

}  // namespace

std::vector<std::string> integrator_names() {
  std::vector<std::string> out;
  for (const auto& [name, _] : registry()) out.push_back(name);
  return out;
}

std::unique_ptr<Integrator> make_integrator(const std::string& name) {
  auto it = registry().find(name);
  if (it == registry().end()) {
    std::string known;
    for (const auto& n : integrator_names()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown integrator '" + name + "' (known: " + known + ")");
  }
  return it->second();
}

}  // namespace pinsim
