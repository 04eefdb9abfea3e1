// XPBD with small steps on the forces' constraints, with the position update done by the
// backend.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>

#include "core/constraints.hpp"
#include "core/format.hpp"
#include "core/integrators.hpp"
#include "core/simulation.hpp"
#include "core/step_context.hpp"
#include "core/xpbd_constraints.hpp"

namespace pinsim {
namespace {

/// Extended position-based dynamics (Macklin, Müller & Chentanez 2016, "XPBD"), in substeps of
/// one or more sweeps (Macklin, Storey, Lu et al. 2019, "Small steps"). Each force that reports
/// constraints (E = sum ks/2 C^2, f = -J^T (ks C + kd J v)) is solved as compliant constraints;
/// every other force acts as an external force. One substep of h = dt / substeps:
///   v += h M^-1 f_ext(x, v)
///   pure dampers (ks = 0, kd > 0), colour by colour: v += h M^-1 f_damp(v') (backward Euler)
///   p = x + h v  (pinned particles: p = x)
///   lambda = 0; `iterations` times, colour by colour, for each constraint j with ks_j > 0:
///     alpha~ = 1 / (ks h^2),  gamma = alpha~ beta h = kd / (ks h)   (beta = kd, eq. 26)
///     dlambda = (-C(p) - alpha~ lambda - gamma J (p - x))
///               / ((1 + gamma) sum_i w_i |J_i|^2 + alpha~)
///     lambda += dlambda;  p_i += w_i J_i dlambda
///   v += (p - p_predicted) / h;  then the backend's drift moves x by h v (= p without
///   contacts), resolving the contacts on the way.
/// So positions move only in the drift, as for every integrator, and a contact's impulse in
/// the drift stays in v. Constraints of one colour share no moving particle, so each colour
/// runs in chunks on threads with the same bits for any thread count. A projection that makes
/// a value non-finite stops the step with a NumericError naming the force, its element and
/// the particle.
class Xpbd : public Integrator {
 public:
  explicit Xpbd(const XpbdSettings& settings) : settings_(settings) {}

  uint32_t substeps() const override { return settings_.substeps; }

  Kick before_drift(StepContext& ctx, double h) override {
    if (!ready_) setup(ctx);
    State& s = ctx.state();
    const Eigen::Index n = s.x.cols();
    compliant_.set_step(h);
    dampers_.set_step(h);
    // 1. External forces: a kick of the substep, in one pass with the prediction unless
    //    dampers come between them.
    const bool kick_apart = any_external_ && dampers_.size() > 0;
    if (any_external_) ctx.compute_forces(s, f_, &external_);
    if (kick_apart) kick(s, f_, h);
    // 2. Pure dampers, on the velocities at x.
    for (std::size_t c = 0; c < dampers_.colours(); ++c)
      sweep(ctx, dampers_, c, [&](std::size_t b, std::size_t e) {
        return dampers_.damp(s.x.data(), s.v.data(), b, e);
      });
    // 3. Prediction p = x + h v.
    predict(s, h, any_external_ && !kick_apart ? &f_ : nullptr);
    // 4. The constraint sweeps, colour by colour.
    const bool keep_lambda = settings_.iterations > 1;
    for (uint32_t it = 0; it < settings_.iterations; ++it)
      for (std::size_t c = 0; c < compliant_.colours(); ++c)
        sweep(ctx, compliant_, c, [&](std::size_t b, std::size_t e) {
          return compliant_.project(s.x.data(), p_.data(), it == 0, keep_lambda, b, e);
        });
    // 5. The velocity the drift moves with: v + (p - p_predicted) / h, with p_predicted = x +
    //    h v recomputed (the same operands as in the prediction, so the same bits).
    const double inv_h = 1.0 / h;
    double* v = s.v.data();
    const double* x = s.x.data();
    const double* p = p_.data();
    const double* w = s.inv_mass.data();
    for_chunks(
        static_cast<std::size_t>(n), kParticleChunk,
        [=](std::size_t, std::size_t b, std::size_t e) {
          for (std::size_t i = b; i < e; ++i) {
            if (!(w[i] > 0.0)) continue;
            const double px = x[2 * i] + h * v[2 * i], py = x[2 * i + 1] + h * v[2 * i + 1];
            v[2 * i] += (p[2 * i] - px) * inv_h;
            v[2 * i + 1] += (p[2 * i + 1] - py) * inv_h;
          }
        },
        Schedule::Even);
    return {};
  }

  nlohmann::json stats() const override {
    nlohmann::json external = nlohmann::json::array();
    for (const auto& l : external_labels_) external.push_back(l);
    return {{"substeps", settings_.substeps},
            {"iterations", settings_.iterations},
            {"constraints", compliant_.size()},
            {"colours", compliant_.colours()},
            {"dampers", dampers_.size()},
            {"damper_colours", dampers_.colours()},
            {"constraints_skipped_ks_kd_0", skipped_},
            {"external_forces", external}};
  }

 private:
  /// Constraints per chunk of a colour (any value gives the same bits).
  static constexpr std::size_t kChunk = 256;

  /// Once: the constraints, their colours, and the forces that act as external forces.
  void setup(StepContext& ctx) {
    ready_ = true;
    const State& s = ctx.state();
    const auto& forces = ctx.forces();
    std::vector<std::string> labels;
    for (std::size_t k = 0; k < forces.size(); ++k) labels.push_back(ctx.force_label(k));
    system_ = ConstraintSystem::gather(forces, labels, static_cast<std::size_t>(s.x.cols()));
    external_.assign(forces.size(), 0);
    for (std::size_t k = 0; k < forces.size(); ++k) {
      if (system_.covers(k)) continue;
      external_[k] = 1;
      any_external_ = true;
      external_labels_.push_back(labels[k]);
      spdlog::info(
          "{}: plugin '{}' reports no constraints (PINSIM_CAP_CONSTRAINTS); xpbd applies its "
          "force as an external force each substep",
          labels[k], forces[k]->plugin().name());
    }
    // ks > 0: compliant constraints. ks = 0 (infinite compliance) with kd > 0: a pure damper,
    // which no compliant constraint can be; ks = kd = 0: no force, left out.
    const std::size_t m = system_.size();
    std::vector<char> compliant(m, 0), damper(m, 0), moves(static_cast<std::size_t>(s.x.cols()));
    for (std::size_t j = 0; j < m; ++j) {
      compliant[j] = system_.ks(j) > 0.0 ? 1 : 0;
      damper[j] = system_.ks(j) == 0.0 && system_.kd(j) > 0.0 ? 1 : 0;
    }
    for (std::size_t i = 0; i < moves.size(); ++i)
      moves[i] = s.inv_mass[static_cast<Eigen::Index>(i)] > 0.0 ? 1 : 0;
    compliant_ = XpbdConstraints(system_, compliant, moves, s.inv_mass);
    dampers_ = XpbdConstraints(system_, damper, moves, s.inv_mass);
    skipped_ = m - compliant_.size() - dampers_.size();
    p_.resize(2, s.x.cols());
    bad_.assign(chunk_count(std::max(compliant_.size(), dampers_.size()), kChunk), 0);
    spdlog::debug(
        "xpbd: {} constraints in {} colours, {} dampers (ks = 0) in {} colours, {} with ks = kd "
        "= 0 skipped; {} substeps of {} iteration(s)",
        compliant_.size(), compliant_.colours(), dampers_.size(), dampers_.colours(), skipped_,
        settings_.substeps, settings_.iterations);
  }

  /// p = x + h v (pinned particles: p = x), after the kick v += h M^-1 f when f is given.
  void predict(State& s, double h, const Eigen::Matrix2Xd* f) {
    double* v = s.v.data();
    double* p = p_.data();
    const double* x = s.x.data();
    const double* w = s.inv_mass.data();
    const double* fd = f != nullptr ? f->data() : nullptr;
    for_chunks(
        static_cast<std::size_t>(s.x.cols()), kParticleChunk,
        [=](std::size_t, std::size_t b, std::size_t e) {
          for (std::size_t i = b; i < e; ++i) {
            if (fd != nullptr) {  // kick(): the same operations
              const double a = h * w[i];
              v[2 * i] += a * fd[2 * i];
              v[2 * i + 1] += a * fd[2 * i + 1];
            }
            const bool moves = w[i] > 0.0;
            p[2 * i] = moves ? x[2 * i] + h * v[2 * i] : x[2 * i];
            p[2 * i + 1] = moves ? x[2 * i + 1] + h * v[2 * i + 1] : x[2 * i + 1];
          }
        },
        Schedule::Even);
  }

  /// Colour c of `set` in fixed chunks of kChunk, each by run(b, e) (which returns the first
  /// position it made non-finite, or kFine); then the first such position, in colour order,
  /// stops the step.
  template <class Run>
  void sweep(StepContext& ctx, XpbdConstraints& set, std::size_t c, Run&& run) {
    const std::size_t b = set.begin(c), e = set.begin(c + 1);
    std::atomic<bool> any{false};  // only ever set: no order to keep
    for_chunks(e - b, kChunk, [&](std::size_t k, std::size_t cb, std::size_t ce) {
      const std::size_t q = run(b + cb, b + ce);
      bad_[k] = q;
      if (q != XpbdConstraints::kFine) any.store(true, std::memory_order_relaxed);
    });
    if (!any.load(std::memory_order_relaxed)) return;
    for (std::size_t k = 0; k < chunk_count(e - b, kChunk); ++k)
      if (bad_[k] != XpbdConstraints::kFine) non_finite(ctx, set, bad_[k]);
  }

  /// Throws the NumericError for the constraint at position q of `set`, whose update made a
  /// coordinate of its first moving particle with one non-finite.
  [[noreturn]] void non_finite(StepContext& ctx, const XpbdConstraints& set, std::size_t q) const {
    const State& s = ctx.state();
    const bool damper = &set == &dampers_;
    const Eigen::Matrix2Xd& out = damper ? s.v : p_;
    const uint32_t j = set.id(q);
    const std::string who = ctx.force_label(system_.force(j));
    int64_t particle = -1;
    std::string list;
    for (uint32_t i : set.particles(q)) {
      list += (list.empty() ? "" : ", ") + std::to_string(i);
      if (particle < 0 && !out.col(i).allFinite()) particle = i;
    }
    const auto i = static_cast<Eigen::Index>(particle);
    const std::string text =
        std::string("non-finite ") + (damper ? "velocity" : "position") + " of particle " +
        std::to_string(particle) + " from xpbd's " + (damper ? "damping" : "projection") + " of " +
        who + " element " + std::to_string(system_.element(j)) + " (particles " + list +
        "; C = " + num(set.c(q)) + ", ks = " + num(system_.ks(j)) + ", kd = " + num(system_.kd(j)) +
        ") at x = (" + num(s.x(0, i)) + ", " + num(s.x(1, i)) + "), v = (" + num(s.v(0, i)) + ", " +
        num(s.v(1, i)) + ")";
    throw NumericError(NumericError::Kind::NonFinite, text, ctx.step(), s.t, particle, who);
  }

  XpbdSettings settings_;
  bool ready_ = false;
  bool any_external_ = false;
  ConstraintSystem system_;
  XpbdConstraints compliant_, dampers_;
  std::vector<char> external_;
  std::vector<std::string> external_labels_;
  std::size_t skipped_ = 0;
  std::vector<std::size_t> bad_;  ///< per chunk of a colour: its first non-finite position
  Eigen::Matrix2Xd f_, p_;
};

}  // namespace

std::unique_ptr<Integrator> make_xpbd(const XpbdSettings& settings) {
  return std::make_unique<Xpbd>(settings);
}

}  // namespace pinsim
