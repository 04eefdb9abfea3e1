// A scene brought to life: plugin instances, the state, and stepping.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <functional>
#include <memory>
#include <pinsim/state.hpp>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/jacobian_entries.hpp"
#include "core/plugin_instance.hpp"
#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "core/step_checks.hpp"

namespace pinsim {

class Integrator;
class StepContext;

/// A run that went numerically wrong: what kind of failure, and where it began.
class NumericError : public std::runtime_error {
 public:
  enum class Kind {
    NonFinite,      ///< a NaN or an infinity in a force or the state
    EnergyBlowup,   ///< a particle's kinetic energy grew past checks.kinetic_growth in one
                    ///< step, or the total energy past checks.energy_blowup
    SolverFailure,  ///< an implicit integrator's linear solve did not converge
  };
  NumericError(Kind kind, const std::string& what, uint64_t step, double t, int64_t particle,
               std::string plugin = "")
      : std::runtime_error(what),
        kind(kind),
        step(step),
        t(t),
        particle(particle),
        plugin(std::move(plugin)) {}
  /// "non_finite", "energy_blowup" or "solver_failure" (summary.json, stress classes).
  const char* kind_name() const {
    return kind == Kind::NonFinite      ? "non_finite"
           : kind == Kind::EnergyBlowup ? "energy_blowup"
                                        : "solver_failure";
  }
  Kind kind;
  uint64_t step;       ///< the step during which it was detected, counting from 1
  double t;            ///< time of the state in which it was found, s
  int64_t particle;    ///< particle where it began, or -1
  std::string plugin;  ///< who is involved: "forces[2] 'linear_spring'", "backend 'sdf'", ...
};

/// Choices that override the scene (from the command line).
struct RunOptions {
  std::string backend;     ///< "" = the scene's
  std::string integrator;  ///< "" = the scene's
  /// Threads for the forces and the backend's per-particle work (--threads), 1 to
  /// kMaxThreads; 0 = the machine's cores. Results are bit-identical for every value
  /// (docs/threads.md).
  unsigned threads = 0;
  /// Time the steps and their parts that run on threads (Simulation::profile; for
  /// pinsim_bench_threads). Off: one branch per part.
  bool profile = false;
};

/// Wall time of the steps so far (RunOptions::profile), and of the parts of them that run
/// their loops on threads when there are threads: Simulation::step's stages up to and with
/// its checks (the forces, the integrator's per-particle passes, the kick, the drift, the
/// after-step check). The rest (the energy check every checks.energy_every steps, the
/// bookkeeping of step(); not the recorder's work) is serial. Serial work inside a part (implicit
/// Euler's solve, a plugin's loop without for_chunks, the sdf backend's chunk sums) counts as
/// threaded, so 1 - threaded / step is a lower bound of the serial fraction.
struct StepProfile {
  uint64_t steps = 0;
  double step_s = 0.0;
  double threaded_s = 0.0;
};

/// The most threads a run may ask for (--threads).
inline constexpr unsigned kMaxThreads = 256;
/// Threads for `requested` (0 = std::thread::hardware_concurrency(), at least 1); always 1
/// in a build without oneTBB.
unsigned resolve_threads(unsigned requested);

class Simulation {
 public:
  /// Loads the plugins the scene names (only those), validates their parameters, creates
  /// instances. Throws SceneError / LoadError / PluginError with locations.
  Simulation(const Scene& scene, PluginLoader& loader, const RunOptions& options = {});
  ~Simulation();

  /// Advances one time step dt, in stages (listed in simulation.cpp): forces, kick, the
  /// backend's drift, the impact correction of its contacts, the integrator's updates after
  /// the drift, checks, bookkeeping. The step owns its contact events: it clears events()
  /// first, then the backend adds the step's contacts (Box2D v3's b2World_Step does the
  /// same). Throws NumericError on NaN/Inf or a kinetic energy growing past
  /// checks.kinetic_growth (both checked every step), or a total energy past
  /// checks.energy_blowup (every checks.energy_every steps). The error names the particle
  /// and the plugin involved.
  void step();

  /// Presses or releases a named input (a flipper, the plunger) at the current state time,
  /// between steps: the next step() sees it, as MuJoCo's controls set between mj_step1 and
  /// mj_step2. Nothing is rebuilt. Throws PluginError if the backend lacks
  /// PINSIM_CAP_INPUTS or does not know the input.
  void set_input(const std::string& name, bool pressed);

  /// f = sum of all forces at state s (f is resized to 2xN and zeroed first); with `include`,
  /// of the forces k with (*include)[k] != 0 only.
  void compute_forces(const State& s, Eigen::Matrix2Xd& f,
                      const std::vector<char>* include = nullptr);
  /// Called after every compute_forces of all the forces (not one with `include`) with the
  /// state and the total force; empty: none. The adjoint's replay keeps the forces of the
  /// step it replays, so as not to evaluate them again.
  using ForceObserver = std::function<void(const State&, const Eigen::Matrix2Xd&)>;
  void set_force_observer(ForceObserver observer) { force_observer_ = std::move(observer); }
  /// The backend's position update of s over dt, no checks: appends its contacts to
  /// events() and returns them (valid until events() changes).
  std::span<const pinsim_event> drift(State& s, double dt);
  /// Force Jacobians at s, 2N x 2N over dofs (2*particle + component): dfdx = sum df/dx,
  /// dfdv = sum df/dv. Forces without a Jacobian get central finite differences of their
  /// add_force (a one-time warning names the plugin); df/dv is differenced only for forces
  /// flagged dissipative or without an energy; differenced columns of pinned particles are
  /// left zero (their dofs never move). Integrators get the entries one force at a time
  /// (StepContext::jacobians).
  void assemble_jacobians(const State& s, Eigen::SparseMatrix<double>& dfdx,
                          Eigen::SparseMatrix<double>& dfdv);
  /// Number of Jacobian evaluations (assemble_jacobians calls, implicit Euler's assemblies).
  uint64_t jacobian_evaluations() const { return jacobian_evals_; }

  double kinetic_energy(const State& s) const;
  /// Sum of the energies of the forces that provide one.
  double potential_energy(const State& s) const;
  /// True when every force provides its energy (the total is then complete).
  bool energy_complete() const;

  State& state() { return state_; }
  const State& state() const { return state_; }
  const Scene& scene() const { return scene_; }
  double dt() const { return scene_.dt; }
  uint64_t step_index() const { return step_; }
  uint64_t force_evaluations() const { return force_evals_; }
  /// The contacts of the last step, read-only (valid until the next step).
  const std::vector<pinsim_event>& events() const { return events_; }
  const std::vector<std::unique_ptr<ForceInstance>>& forces() const { return forces_; }
  const BackendInstance& backend() const { return *backend_; }
  /// The backend, to start or stop its drift recording (the adjoint of a run).
  BackendInstance& backend() { return *backend_; }
  const std::string& integrator_name() const { return integrator_name_; }
  /// Threads the steps run on (RunOptions::threads resolved; 1 without oneTBB).
  unsigned threads() const { return threads_; }
  /// The times RunOptions::profile asked for (zeros without it).
  const StepProfile& profile() const { return profile_; }
  /// The integrator's own figures for summary.json (implicit Euler: its linear solves), or
  /// null when it has none.
  nlohmann::json integrator_stats() const;
  double energy_start() const { return e0_; }
  double max_energy_drift() const { return max_drift_; }

 private:
  friend class StepContext;
  friend class Integrator;  // Integrator::step: the stages without the checks

  /// Stages 1 to 5 of step() for n substeps of h / n (checks: the step's, or none).
  void substep_stages(StepContext& ctx, Integrator& integrator, double h, uint32_t n,
                      StepChecks* checks);
  /// Force k's entries, as StepContext::jacobians hands them over; not counted.
  void jacobians_of(std::size_t k, const State& s, const pinsim_triplet_sink& sx,
                    const pinsim_triplet_sink& sv);
  /// The force whose Jacobian weighs most in M - h df/dv - h^2 df/dx at s (see
  /// StepContext::stiffest_force), its weight in `weight`; -1 if none has a Jacobian entry.
  int64_t stiffest_force(const State& s, double h, double& weight);
  /// "forces[2] 'linear_spring'": force k by its place in the scene's forces array.
  std::string force_label(std::size_t k) const;
  void check_finite_forces(const State& s, const Eigen::Matrix2Xd& f) const;
  [[noreturn]] void throw_step_finding(const StepFinding& found, double t_end) const;
  void check_energy();
  /// The force contributing the largest |f| to particle i at s (its magnitude in `mag`), or
  /// -1 if none acts on it; a non-finite contribution counts as the largest.
  int64_t strongest_force(const State& s, Eigen::Index i, double& mag) const;
  /// "; largest force on it: forces[0] 'gravity' (|f| = 9.81)", and the plugin for errors.
  std::string strongest_force_text(const State& s, Eigen::Index i, std::string& plugin) const;

  struct ThreadLimit;  ///< oneTBB's limit of threads_ threads (none in a serial build)

  Scene scene_;
  State state_;
  unsigned threads_ = 1;
  bool profiling_ = false;
  StepProfile profile_;
  std::unique_ptr<ThreadLimit> limit_;
  std::vector<std::unique_ptr<ForceInstance>> forces_;
  std::unique_ptr<BackendInstance> backend_;
  std::unique_ptr<Integrator> integrator_;
  std::string integrator_name_;
  std::vector<pinsim_event> events_;
  uint64_t step_ = 0;
  uint64_t force_evals_ = 0;
  ForceObserver force_observer_;
  uint64_t jacobian_evals_ = 0;
  /// per force: finite-difference warning already given (bytes, not vector<bool>: forces'
  /// Jacobians may be asked for on two threads at once, jacobians_of)
  std::vector<char> fd_warned_;
  StepChecks checks_;
  Eigen::VectorXd k_at_check_;  ///< kinetic energy per particle at the last energy check
  double e0_ = 0.0;
  double e_scale_ = 0.0;
  double max_drift_ = 0.0;
};

}  // namespace pinsim
