#include "core/simulation.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>
#ifdef PINSIM_WITH_TBB
#include <tbb/global_control.h>
#endif

#include "core/instances.hpp"
#include "core/integrator.hpp"
#include "core/integrators.hpp"
#include "core/step_context.hpp"

namespace pinsim {
namespace {

void emit_event(void* ctx, const pinsim_event* e) {
  static_cast<std::vector<pinsim_event>*>(ctx)->push_back(*e);
}

void add_triplet(void* ctx, uint32_t row, uint32_t col, double value) {
  static_cast<std::vector<Eigen::Triplet<double>>*>(ctx)->emplace_back(row, col, value);
}

/// Central differences of one force's add_force in x (wrt_v false) or v (true): column j of
/// the Jacobian is (f(q + eps e_j) - f(q - eps e_j)) / (2 eps), eps = 1e-6 max(1, |q_j|)
/// (error O(eps^2) times the third derivative, rounding O(1e-16 |f| / eps)).
void fd_jacobian(const ForceInstance& force, const State& s, bool wrt_v,
                 std::vector<Eigen::Triplet<double>>& out) {
  State p = s;
  Eigen::Matrix2Xd fp(2, s.x.cols()), fm(2, s.x.cols());
  Eigen::Matrix2Xd& q = wrt_v ? p.v : p.x;
  const Eigen::Index n = q.size();
  for (Eigen::Index j = 0; j < n; ++j) {
    if (!(s.inv_mass[j / 2] > 0.0)) continue;  // pinned dofs never move
    const double q0 = q.data()[j];
    const double eps = 1e-6 * std::max(1.0, std::abs(q0));
    q.data()[j] = q0 + eps;
    fp.setZero();
    force.add_force(p.view(), fp.data());
    q.data()[j] = q0 - eps;
    fm.setZero();
    force.add_force(p.view(), fm.data());
    q.data()[j] = q0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double d = (fp.data()[i] - fm.data()[i]) / (2.0 * eps);
      if (d != 0.0) out.emplace_back(static_cast<int>(i), static_cast<int>(j), d);
    }
  }
}

}  // namespace

#ifdef PINSIM_WITH_TBB
struct Simulation::ThreadLimit {
  explicit ThreadLimit(unsigned n) : control(tbb::global_control::max_allowed_parallelism, n) {}
  tbb::global_control control;
};
#else
struct Simulation::ThreadLimit {};
#endif

unsigned resolve_threads(unsigned requested) {
#ifdef PINSIM_WITH_TBB
  const unsigned n = requested != 0 ? requested : std::thread::hardware_concurrency();
  return std::clamp(n, 1u, kMaxThreads);
#else
  (void)requested;
  return 1;
#endif
}

Simulation::Simulation(const Scene& scene, PluginLoader& loader, const RunOptions& options)
    : scene_(scene),
      state_(scene.initial_state()),
      threads_(resolve_threads(options.threads)),
      profiling_(options.profile) {
#ifdef PINSIM_WITH_TBB
  // The plugins' parallel loops (oneTBB) run on at most threads_ threads while this
  // simulation lives: a process-wide limit, set once, so a step pays nothing for it (a
  // task_arena would be entered every step, at a cost comparable to a one-ball step). With
  // several simulations alive the smallest limit holds for all; results do not change.
  limit_ = std::make_unique<ThreadLimit>(threads_);
#endif
  integrator_name_ = options.integrator.empty() ? scene_.integrator : options.integrator;
  try {
    integrator_ = make_integrator(integrator_name_, scene_.xpbd);
  } catch (const std::invalid_argument& e) {
    throw SceneError(scene_.label + ": integrator: " + e.what());
  }

  PluginRef bref = scene_.backend;
  if (!options.backend.empty() && options.backend != bref.name) {
    // Another backend's parameters do not apply; it starts from its defaults.
    bref = PluginRef{options.backend, "", nlohmann::json::object(), "--backend " + options.backend};
  }
  backend_ = create_backend(scene_, loader, bref, scene_.backend_scene, state_);
  for (const auto& f : scene_.forces) forces_.push_back(create_force(scene_, loader, f, state_));
  fd_warned_.assign(forces_.size(), 0);

  e0_ = kinetic_energy(state_) + potential_energy(state_);
  // Energy scale for relative drift: total |terms| at the start, never zero.
  e_scale_ = kinetic_energy(state_);
  for (const auto& f : forces_)
    if (f->has_energy()) e_scale_ += std::abs(f->energy(state_.view()));
  checks_.start(state_, e_scale_, scene_.kinetic_growth);
  if (!(e_scale_ > 0.0)) e_scale_ = 1.0;
  k_at_check_.resize(static_cast<Eigen::Index>(state_.size()));
  for (Eigen::Index i = 0; i < k_at_check_.size(); ++i)
    k_at_check_[i] =
        state_.inv_mass[i] > 0.0 ? 0.5 * state_.v.col(i).squaredNorm() / state_.inv_mass[i] : 0.0;
}

Simulation::~Simulation() = default;

nlohmann::json Simulation::integrator_stats() const { return integrator_->stats(); }

void Simulation::set_input(const std::string& name, bool pressed) {
  backend_->input(name, pressed, state_.t);
}

void Simulation::compute_forces(const State& s, Eigen::Matrix2Xd& f,
                                const std::vector<char>* include) {
  const Eigen::Index n = s.x.cols();
  const bool one_chunk = n < static_cast<Eigen::Index>(kParallelItems);
  if (one_chunk) {  // one chunk: the serial loop, with nothing else on the way
    f.setZero(2, n);
  } else {
    f.resize(2, n);
    per_particle(n, [&](Eigen::Index b, Eigen::Index k) { f.middleCols(b, k).setZero(); });
  }
  const pinsim_state_view view = s.view();
  for (std::size_t k = 0; k < forces_.size(); ++k)
    if (include == nullptr || (*include)[k] != 0) forces_[k]->add_force(view, f.data());
  ++force_evals_;
  if (one_chunk) {
    if (!f.allFinite()) check_finite_forces(s, f);
  } else {
    // whether every force is finite, per chunk (a flag: no order to keep); the search for
    // the culprit runs only when one is not
    std::atomic<bool> non_finite{false};
    per_particle(n, [&](Eigen::Index b, Eigen::Index k) {
      if (!f.middleCols(b, k).allFinite()) non_finite.store(true, std::memory_order_relaxed);
    });
    if (non_finite.load(std::memory_order_relaxed)) check_finite_forces(s, f);
  }
  if (force_observer_ && include == nullptr) force_observer_(s, f);
}

std::span<const pinsim_event> Simulation::drift(State& s, double dt) {
  const std::size_t first = events_.size();
  const pinsim_event_sink sink{&events_, &emit_event};
  backend_->advance(s, dt, &sink);
  return std::span<const pinsim_event>(events_).subspan(first);
}

void Simulation::assemble_jacobians(const State& s, Eigen::SparseMatrix<double>& dfdx,
                                    Eigen::SparseMatrix<double>& dfdv) {
  JacobianEntries ex, ev;
  for (std::size_t k = 0; k < forces_.size(); ++k) jacobians_of(k, s, ex.sink(), ev.sink());
  ++jacobian_evals_;
  std::vector<Eigen::Triplet<double>> tx, tv;
  ex.append_triplets(tx);
  ev.append_triplets(tv);
  const auto n = static_cast<Eigen::Index>(2 * s.size());
  dfdx.resize(n, n);
  dfdv.resize(n, n);
  dfdx.setFromTriplets(tx.begin(), tx.end());
  dfdv.setFromTriplets(tv.begin(), tv.end());
}

void Simulation::jacobians_of(std::size_t k, const State& s, const pinsim_triplet_sink& sx,
                              const pinsim_triplet_sink& sv) {
  const pinsim_state_view view = s.view();
  const ForceInstance& f = *forces_[k];
  const bool has_x = f.provides_dfdx(), has_v = f.provides_dfdv();
  const bool need_v = f.velocity_dependent();
  if (has_x || has_v) f.add_jacobians(view, has_x ? &sx : nullptr, has_v ? &sv : nullptr);
  if (!has_x || (!has_v && need_v)) {
    if (!fd_warned_[k]) {
      fd_warned_[k] = true;
      spdlog::warn(
          "{}: plugin '{}' provides no {} Jacobian; using central finite differences of its "
          "force (2 force evaluations per degree of freedom per step)",
          f.context(), f.plugin().name(), !has_x ? "df/dx" : "df/dv");
    }
    std::vector<Eigen::Triplet<double>> fd;
    auto append = [&](const pinsim_triplet_sink& to) {
      for (const auto& e : fd)
        to.add(to.context, static_cast<uint32_t>(e.row()), static_cast<uint32_t>(e.col()),
               e.value());
      fd.clear();
    };
    if (!has_x) {
      fd_jacobian(f, s, false, fd);
      append(sx);
    }
    if (!has_v && need_v) {
      fd_jacobian(f, s, true, fd);
      append(sv);
    }
  }
}

int64_t Simulation::stiffest_force(const State& s, double h, double& weight) {
  const pinsim_state_view view = s.view();
  int64_t best = -1;
  weight = 0.0;
  for (std::size_t k = 0; k < forces_.size(); ++k) {
    const ForceInstance& f = *forces_[k];
    std::vector<Eigen::Triplet<double>> tx, tv;
    const pinsim_triplet_sink sx{&tx, &add_triplet, nullptr}, sv{&tv, &add_triplet, nullptr};
    const bool has_x = f.provides_dfdx(), has_v = f.provides_dfdv();
    if (has_x || has_v) f.add_jacobians(view, has_x ? &sx : nullptr, has_v ? &sv : nullptr);
    if (!has_x) fd_jacobian(f, s, false, tx);
    if (!has_v && f.velocity_dependent()) fd_jacobian(f, s, true, tv);
    double w = 0.0;
    auto weigh = [&](const std::vector<Eigen::Triplet<double>>& t, double factor) {
      for (const auto& e : t) {
        const double a = factor * std::abs(e.value()) * s.inv_mass[e.row() / 2];
        if (!(a <= w)) w = a;  // a NaN weighs most
      }
    };
    weigh(tx, h * h);
    weigh(tv, h);
    if (std::isnan(w) || w > weight) {
      weight = w;
      best = static_cast<int64_t>(k);
    }
    if (std::isnan(w)) break;  // nothing weighs more
  }
  return best;
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

void Simulation::step() {
  const double h = scene_.dt;
  // Time at the end of the step from the step count, so t carries no accumulated rounding.
  const double t_end = static_cast<double>(step_ + 1) * h;
  using Clock = std::chrono::steady_clock;
  Clock::time_point t0, t1;  // RunOptions::profile: three branches a step without it
  if (profiling_) t0 = Clock::now();
  // Why the step does not depend on threads_: the stages run one after another on this
  // thread, and the loops within them (the forces', the integrator's, the backend's, the
  // checks') split their particles or elements into chunks fixed by the counts alone and
  // combine what they sum in chunk order (docs/threads.md).
  StepContext ctx(*this);
  events_.clear();

  const uint32_t substeps = integrator_->substeps();
  if (substeps > 1) {
    // 1.-5. once per substep, each with its drift (substep_stages)
    substep_stages(ctx, *integrator_, h, substeps, &checks_);
  } else {
    // 1. Forces, and the integrator's velocity updates up to the drift.
    const Kick kick = integrator_->before_drift(ctx, h);
    // 2. Kick: the last of those updates, v += h M^-1 f, in one pass with the checks' copy of
    //    the velocities entering the drift.
    if (kick.f != nullptr)
      pinsim::kick(state_, *kick.f, kick.h, &checks_.entering_drift());
    else
      checks_.before_drift(state_);
    // 3. Drift through the backend: the positions, and the contacts on the way.
    const std::span<const pinsim_event> contacts = drift(state_, h);
    const bool acts_after = integrator_->acts_after_drift();
    if (acts_after)
      checks_.after_drift(state_);
    else
      checks_.after_last_drift();
    // 4. Impact correction: each contact's impulse moved to the velocity at its time.
    if (!contacts.empty())
      correct_impacts(state_, contacts, state_.t, integrator_->impact_reference(state_, h));
    // 5. The integrator's velocity updates after the drift (closing kicks).
    if (acts_after) integrator_->after_drift(ctx, h);
  }
  // 6. Checks: a finite state, and each particle's kinetic energy within the growth bound.
  const StepFinding found = checks_.check(state_);
  if (profiling_) t1 = Clock::now();
  if (found) throw_step_finding(found, t_end);
  // 7. Bookkeeping: the time, the step count, the total energy every checks.energy_every.
  state_.t = t_end;
  ++step_;
  if (step_ % scene_.energy_every == 0) check_energy();
  if (profiling_) {
    ++profile_.steps;
    profile_.threaded_s += std::chrono::duration<double>(t1 - t0).count();
    profile_.step_s += std::chrono::duration<double>(Clock::now() - t0).count();
  }
}

// Stages 1 to 5 of Simulation::step for each of n substeps of h / n: substep k starts at
// t0 + k h / n (the state's time during its stages; the step's bookkeeping sets the end time).
// The checks see the sum of the velocity changes the drifts made, and a state made non-finite
// in a drift stops the step at that drift.
void Simulation::substep_stages(StepContext& ctx, Integrator& integrator, double h, uint32_t n,
                                StepChecks* checks) {
  const double hs = h / static_cast<double>(n);
  const double t0 = state_.t;
  if (checks != nullptr) checks->begin_drifts(state_);
  for (uint32_t k = 0; k < n; ++k) {
    state_.t = t0 + static_cast<double>(k) * hs;
    const Kick kick = integrator.before_drift(ctx, hs);
    if (kick.f != nullptr) pinsim::kick(state_, *kick.f, kick.h);
    if (checks != nullptr) checks->before_substep_drift(state_);
    const std::span<const pinsim_event> contacts = drift(state_, hs);
    if (checks != nullptr) {
      const StepFinding found = checks->after_substep_drift(state_);
      if (found) throw_step_finding(found, t0 + static_cast<double>(k + 1) * hs);
    }
    if (!contacts.empty())
      correct_impacts(state_, contacts, state_.t, integrator.impact_reference(state_, hs));
    if (integrator.acts_after_drift()) integrator.after_drift(ctx, hs);
  }
  state_.t = t0;
  if (checks != nullptr) checks->end_drifts();
}

// Stages 1 to 5 of Simulation::step, in its order, without the checks' copies.
void Integrator::step(Simulation& sim, double h) {
  StepContext ctx(sim);
  State& s = sim.state_;
  sim.events_.clear();
  if (substeps() > 1) {
    sim.substep_stages(ctx, *this, h, substeps(), nullptr);
    return;
  }
  const Kick k = before_drift(ctx, h);
  if (k.f != nullptr) kick(s, *k.f, k.h);
  const std::span<const pinsim_event> contacts = sim.drift(s, h);
  if (!contacts.empty()) correct_impacts(s, contacts, s.t, impact_reference(s, h));
  if (acts_after_drift()) after_drift(ctx, h);
}

State& StepContext::state() const { return sim_.state_; }
uint64_t StepContext::step() const { return sim_.step_ + 1; }
const std::vector<std::unique_ptr<ForceInstance>>& StepContext::forces() const {
  return sim_.forces_;
}
void StepContext::compute_forces(const State& s, Eigen::Matrix2Xd& f,
                                 const std::vector<char>* include) const {
  sim_.compute_forces(s, f, include);
}
std::string StepContext::force_label(std::size_t k) const { return sim_.force_label(k); }
std::size_t StepContext::threads() const { return sim_.threads_; }
void StepContext::jacobians(std::size_t k, const State& s, const pinsim_triplet_sink& dfdx,
                            const pinsim_triplet_sink& dfdv) const {
  sim_.jacobians_of(k, s, dfdx, dfdv);
}
void StepContext::count_jacobian_evaluation() const { ++sim_.jacobian_evals_; }
std::string StepContext::stiffest_force(const State& s, double h, double& weight) const {
  const int64_t k = sim_.stiffest_force(s, h, weight);
  return k < 0 ? std::string() : sim_.force_label(static_cast<std::size_t>(k));
}

}  // namespace pinsim
