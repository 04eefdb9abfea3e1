// XPBD with small steps on the forces' constraints, with the position update done by the
// backend.
#include <spdlog/spdlog.h>

#include <cmath>

#include "core/constraint_colouring.hpp"
#include "core/constraints.hpp"
#include "core/integrators.hpp"
#include "core/step_context.hpp"

namespace pinsim {
namespace {

/// Extended position-based dynamics (Macklin, Müller & Chentanez 2016, "XPBD"), in substeps of
/// one or more sweeps (Macklin, Storey, Lu et al. 2019, "Small steps"). Each force that reports
/// constraints (E = sum ks/2 C^2, f = -J^T (ks C + kd J v)) is solved as compliant constraints;
/// every other force acts as an external force. One substep of h = dt / substeps:
///   v += h M^-1 f_ext(x, v);  p = x + h v  (pinned particles: p = x)
///   lambda = 0; `iterations` times, colour by colour, for each constraint j with ks_j > 0:
///     alpha~ = 1 / (ks h^2),  gamma = alpha~ beta h = kd / (ks h)   (beta = kd, eq. 26)
///     dlambda = (-C(p) - alpha~ lambda - gamma J (p - x))
///               / ((1 + gamma) sum_i w_i |J_i|^2 + alpha~)
///     lambda += dlambda;  p_i += w_i J_i dlambda
///   v += (p - p_predicted) / h;  then the backend's drift moves x by h v (= p without
///   contacts), resolving the contacts on the way.
/// So positions move only in the drift, as for every integrator, and a contact's impulse in
/// the drift stays in v. Constraints of one colour share no moving particle, so each colour
/// runs in chunks on threads with the same bits for any thread count.
class Xpbd : public Integrator {
 public:
  explicit Xpbd(const XpbdSettings& settings) : settings_(settings) {}

  uint32_t substeps() const override { return settings_.substeps; }

  Kick before_drift(StepContext& ctx, double h) override {
    if (!ready_) setup(ctx);
    State& s = ctx.state();
    const Eigen::Index n = s.x.cols();
    // 1. External forces: a kick of the substep.
    if (any_external_) {
      ctx.compute_forces(s, f_, &external_);
      kick(s, f_, h);
    }
    // 2. Prediction p = x + h v.
    p_.resize(2, n);
    p0_.resize(2, n);
    per_particle(n, [&](Eigen::Index b, Eigen::Index k) {
      for (Eigen::Index i = b; i < b + k; ++i) {
        p_.col(i) = s.inv_mass[i] > 0.0 ? Eigen::Vector2d(s.x.col(i) + h * s.v.col(i))
                                        : Eigen::Vector2d(s.x.col(i));
        p0_.col(i) = p_.col(i);
      }
    });
    // 3. The constraint sweeps, colour by colour.
    std::fill(lambda_.begin(), lambda_.end(), 0.0);
    for (uint32_t it = 0; it < settings_.iterations; ++it)
      for (std::size_t c = 0; c < colouring_.colours(); ++c) {
        const std::size_t b = colouring_.start[c], e = colouring_.start[c + 1];
        for_chunks(e - b, kChunk, [&](std::size_t, std::size_t cb, std::size_t ce) {
          project(s, h, b + cb, b + ce);
        });
      }
    // 4. The velocity the drift moves with: v + (p - p_predicted) / h.
    const double inv_h = 1.0 / h;
    per_particle(n, [&](Eigen::Index b, Eigen::Index k) {
      for (Eigen::Index i = b; i < b + k; ++i)
        if (s.inv_mass[i] > 0.0) s.v.col(i) += (p_.col(i) - p0_.col(i)) * inv_h;
    });
    return {};
  }

  nlohmann::json stats() const override {
    nlohmann::json external = nlohmann::json::array();
    for (const auto& l : external_labels_) external.push_back(l);
    return {{"substeps", settings_.substeps},  {"iterations", settings_.iterations},
            {"constraints", ids_.size()},      {"constraints_skipped_ks_0", skipped_},
            {"colours", colouring_.colours()}, {"external_forces", external}};
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
    // ks = 0: infinite compliance, no force; left out.
    std::vector<char> include(system_.size(), 0), moves(static_cast<std::size_t>(s.x.cols()));
    for (std::size_t j = 0; j < system_.size(); ++j) include[j] = system_.ks(j) > 0.0 ? 1 : 0;
    for (std::size_t i = 0; i < moves.size(); ++i)
      moves[i] = s.inv_mass[static_cast<Eigen::Index>(i)] > 0.0 ? 1 : 0;
    colouring_ = colour_constraints(system_, include, moves);
    skipped_ = system_.size() - colouring_.order.size();
    // The constraints in colour order, with their particles and coefficients.
    ids_ = colouring_.order;
    slot_.assign(1, 0);
    for (uint32_t j : ids_) {
      elements_.push_back(system_.element(j));
      for (uint32_t i : system_.particles(j)) particles_.push_back(i);
      slot_.push_back(particles_.size());
      ks_.push_back(system_.ks(j));
      kd_.push_back(system_.kd(j));
    }
    lambda_.assign(ids_.size(), 0.0);
    c_.assign(ids_.size(), 0.0);
    dc_.assign(2 * particles_.size(), 0.0);
    spdlog::debug(
        "xpbd: {} constraints in {} colours ({} with ks = 0 skipped), {} substeps of {} "
        "iteration(s)",
        ids_.size(), colouring_.colours(), skipped_, settings_.substeps, settings_.iterations);
  }

  /// Projects the constraints [b, e) of one colour (colour order) onto p_.
  void project(const State& s, double h, std::size_t b, std::size_t e) {
    system_.evaluate(p_.data(), ids_.data() + b, elements_.data() + b, e - b, c_.data() + b,
                     dc_.data() + 2 * slot_[b]);
    double* p = p_.data();
    const double* x = s.x.data();
    const double* w = s.inv_mass.data();
    for (std::size_t q = b; q < e; ++q) {
      const double* g = dc_.data() + 2 * slot_[q];
      const uint32_t* id = particles_.data() + slot_[q];
      const std::size_t m = slot_[q + 1] - slot_[q];
      double sw = 0.0, gdx = 0.0;
      for (std::size_t a = 0; a < m; ++a) {
        const uint32_t i = id[a];
        sw += w[i] * (g[2 * a] * g[2 * a] + g[2 * a + 1] * g[2 * a + 1]);
        gdx += g[2 * a] * (p[2 * i] - x[2 * i]) + g[2 * a + 1] * (p[2 * i + 1] - x[2 * i + 1]);
      }
      // alpha~ = alpha / h^2 with alpha = 1 / ks (0 for an infinitely stiff constraint)
      const double at = 1.0 / (ks_[q] * h * h);
      const double gamma = kd_[q] == 0.0 ? 0.0 : at * kd_[q] * h;
      const double denom = (1.0 + gamma) * sw + at;
      if (!(denom > 0.0)) continue;  // no moving particle, or a zero gradient
      const double dl = (-c_[q] - at * lambda_[q] - gamma * gdx) / denom;
      lambda_[q] += dl;
      for (std::size_t a = 0; a < m; ++a) {
        const uint32_t i = id[a];
        if (!(w[i] > 0.0)) continue;  // pinned: never written (other colours share it)
        p[2 * i] += w[i] * dl * g[2 * a];
        p[2 * i + 1] += w[i] * dl * g[2 * a + 1];
      }
    }
  }

  XpbdSettings settings_;
  bool ready_ = false;
  bool any_external_ = false;
  ConstraintSystem system_;
  ConstraintColouring colouring_;
  std::vector<char> external_;
  std::vector<std::string> external_labels_;
  std::size_t skipped_ = 0;
  // per constraint in colour order
  std::vector<uint32_t> ids_;
  std::vector<uint64_t> elements_;
  std::vector<std::size_t> slot_;  ///< its particles: particles_[slot_[q] .. slot_[q + 1])
  std::vector<uint32_t> particles_;
  std::vector<double> ks_, kd_, lambda_, c_, dc_;
  Eigen::Matrix2Xd f_, p_, p0_;
};

}  // namespace

std::unique_ptr<Integrator> make_xpbd(const XpbdSettings& settings) {
  return std::make_unique<Xpbd>(settings);
}

}  // namespace pinsim
