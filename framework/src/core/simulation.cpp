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
    integrator_ = make_integrator(integrator_name_);
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

void Simulation::compute_forces(const State& s, Eigen::Matrix2Xd& f) {
  const Eigen::Index n = s.x.cols();
  const bool one_chunk = n < static_cast<Eigen::Index>(kParallelItems);
  if (one_chunk) {  // one chunk: the serial loop, with nothing else on the way
    f.setZero(2, n);
  } else {
    f.resize(2, n);
    per_particle(n, [&](Eigen::Index b, Eigen::Index k) { f.middleCols(b, k).setZero(); });
  }
  const pinsim_state_view view = s.view();
  for (const auto& force : forces_) force->add_force(view, f.data());
  ++force_evals_;
  if (one_chunk) {
    if (!f.allFinite()) check_finite_forces(s, f);
    return;
  }
  // whether every force is finite, per chunk (a flag: no order to keep); the search for the
  // culprit runs only when one is not
  std::atomic<bool> non_finite{false};
  per_particle(n, [&](Eigen::Index b, Eigen::Index k) {
    if (!f.middleCols(b, k).allFinite()) non_finite.store(true, std::memory_order_relaxed);
  });
  if (non_finite.load(std::memory_order_relaxed)) check_finite_forces(s, f);
}

void Simulation::drift(State& s, double dt) {
  const pinsim_event_sink sink{&events_, &emit_event};
  const bool own = &s == &state_;
  if (own) checks_.before_drift(s);
  backend_->advance(s, dt, &sink);
  if (own) checks_.after_drift(s);
}

void Simulation::kick_drift(State& s, const Eigen::Matrix2Xd& f, double h) {
  if (&s != &state_) {
    kick(s, f, h);
    drift(s, h);
    return;
  }
  checks_.kick_before_drift(s, f, h);
  const pinsim_event_sink sink{&events_, &emit_event};
  backend_->advance(s, h, &sink);
  checks_.after_last_drift();
}

void Simulation::assemble_jacobians(const State& s, Eigen::SparseMatrix<double>& dfdx,
                                    Eigen::SparseMatrix<double>& dfdv) {
  const auto n = static_cast<Eigen::Index>(2 * s.size());
  std::vector<Eigen::Triplet<double>> tx, tv;
  jacobian_triplets(s, tx, tv);
  dfdx.resize(n, n);
  dfdv.resize(n, n);
  dfdx.setFromTriplets(tx.begin(), tx.end());
  dfdv.setFromTriplets(tv.begin(), tv.end());
}

void Simulation::jacobian_triplets(const State& s, std::vector<Eigen::Triplet<double>>& tx,
                                   std::vector<Eigen::Triplet<double>>& tv) {
  JacobianEntries ex, ev;
  jacobian_entries(s, ex, ev);
  tx.clear();
  tv.clear();
  ex.append_triplets(tx);
  ev.append_triplets(tv);
}

void Simulation::jacobian_entries(const State& s, JacobianEntries& ex, JacobianEntries& ev) {
  ex.clear();
  ev.clear();
  jacobians(s, ex.sink(), ev.sink());
}

void Simulation::jacobians(const State& s, const pinsim_triplet_sink& sx,
                           const pinsim_triplet_sink& sv) {
  for (std::size_t k = 0; k < forces_.size(); ++k) jacobians_of(k, s, sx, sv);
  ++jacobian_evals_;
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
  // Time at the end of the step from the step count, so t carries no accumulated rounding.
  const double t_end = static_cast<double>(step_ + 1) * scene_.dt;
  using Clock = std::chrono::steady_clock;
  Clock::time_point t0, t1;  // RunOptions::profile: three branches a step without it
  if (profiling_) t0 = Clock::now();
  events_.clear();
  // Plugins' parallel loops split their work in fixed chunks and combine them in a fixed
  // order, so the step does not depend on threads_ (docs/threads.md).
  integrator_->step(*this, scene_.dt);
  const StepFinding found = checks_.check(state_);
  if (profiling_) t1 = Clock::now();
  if (found) throw_step_finding(found, t_end);
  state_.t = t_end;
  ++step_;
  if (step_ % scene_.energy_every == 0) check_energy();
  if (profiling_) {
    ++profile_.steps;
    profile_.threaded_s += std::chrono::duration<double>(t1 - t0).count();
    profile_.step_s += std::chrono::duration<double>(Clock::now() - t0).count();
  }
}

}  // namespace pinsim
