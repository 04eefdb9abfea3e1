// Linearized backward Euler (Baraff & Witkin 1998, "Large steps in cloth simulation", eq. 6).
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/integrators.hpp"
#include "core/simulation.hpp"

namespace pinsim {
namespace {

/// Backward Euler v_{n+1} = v_n + h M^-1 f(x_{n+1}, v_{n+1}), x_{n+1} = x_n + h v_{n+1},
/// linearized once about (x_n, v_n) with K = df/dx, D = df/dv:
///   (M - h D - h^2 K) dv = h (f_n + h K v_n),   v_{n+1} = v_n + dv,
/// then the backend drifts x with v_{n+1}. Exact backward Euler for linear forces: on the
/// harmonic oscillator the energy shrinks by exactly 1/(1 + (h w)^2) per step, for any h.
/// Pinned dofs (inv_mass 0) keep dv = 0: their rows and columns become the identity.
/// A is symmetric for conservative forces, but not always: a damped spring's df/dx has the
/// nonsymmetric term -kd J^T (H v)^T when the spring turns. Eigen's ConjugateGradient with
/// Lower|Upper on a column-major matrix multiplies by A^T (it assumes symmetry), so on such a
/// system it would solve A^T dv = b. Each step therefore checks A's symmetry up to rounding
/// (every slot against the slot of its transpose entry, found once with the pattern; see
/// is_symmetric()) and solves a symmetric A by conjugate gradients, a nonsymmetric
/// one by BiCGSTAB (which multiplies by A itself), both with a Jacobi (diagonal)
/// preconditioner to a relative residual of 1e-12, started from the last step's dv (warm
/// start: a smooth motion changes dv little from step to step) when that guess's residual is
/// below |b|, else from 0. A is assembled in a sparsity pattern built once (rebuilt only if
/// the forces' entries move): no sorting or allocation per step; if the iterative solve fails
/// (an indefinite K from compressed springs can make CG fail) a sparse LU solves it instead. If
/// that fails too (a singular system, or a residual above 1e-8 of |b|), the step throws
/// NumericError (solver_failure) rather than use an unconverged velocity. stats() reports the
/// solves for summary.json.
///
/// A converged solve can still be meaningless. CG stops at |A dv - b| <= 1e-12 |b|, and a
/// very stiff force makes |b| huge (h^2 K v) while the soft directions of A keep eigenvalues
/// near the masses. When the forces' Jacobians are negative semidefinite (springs in tension,
/// damping), A = M + h^2 (-K) + h (-D) >= M; with C = M^-1/2 A M^-1/2 >= I the error
/// e = dv - dv* = A^-1 r (r = A dv - b) obeys, in the mass-weighted (kinetic) norm,
///   |e|_M^2 = r^T M^-1/2 C^-2 M^-1/2 r <= r^T M^-1 r,   |e|_M <= (sum_i r_i^2 / m_i)^1/2.
/// The solve is refused when that bound exceeds 1e-3 (|v_n|_M^2 + |dv|_M^2)^1/2 (a 0.1 %
/// error relative to the velocity and its change; with ks = 1e300 the bound is as large as
/// the velocities themselves), naming the particle with the largest r_i^2 / m_i and the
/// force with the largest (h^2 |df/dx| + h |df/dv|) / m (for a spring, (h w)^2), the one that
/// made the system ill-conditioned. Stiff but representable systems pass: |b| ~ |A dv|, so
/// the bound is about 1e-12 (h w)^2 |dv|_M (plus rounding, 1e-16 (h w)^2 |dv|_M), under
/// 1e-3 |dv|_M up to (h w)^2 ~ 1e9. (|v_{n+1}| alone would not do: a very stiff step sets
/// v_{n+1} ~ 0 by cancellation, v_n + dv.)
class ImplicitEuler : public Integrator {
 public:
  explicit ImplicitEuler(const ImplicitEulerOptions& o) : options_(o) {}

  void step(Simulation& sim, double h) override {
    State& s = sim.state();
    sim.compute_forces(s, f_);
    const Eigen::Index n = 2 * static_cast<Eigen::Index>(s.size());
    const Eigen::Map<const Eigen::VectorXd> f(f_.data(), n), v0(s.v.data(), n);

    if (m_.size() != n) m_.resize(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const double w = s.inv_mass[i / 2];
      m_[i] = w > 0.0 ? 1.0 / w : 0.0;
    }
    const Eigen::VectorXd& m = m_;
    // A, and K v_n straight from the entries; b = h (f_n + h K v_n), pinned rows zeroed.
    if (kv_.size() != n) kv_.resize(n);
    assemble(sim, s, n, h, v0);
    if (b_.size() != n) b_.resize(n);
    b_ = h * (f + h * kv_);
    for (Eigen::Index i = 0; i < n; ++i)
      if (!(m[i] > 0.0)) b_[i] = 0.0;
    const Eigen::VectorXd& b = b_;
    const bool symmetric = is_symmetric();
    const Eigen::Index max_iterations = options_.cg_max_iterations > 0
                                            ? options_.cg_max_iterations
                                            : std::max<Eigen::Index>(100, 4 * n);
    // Warm start from the last step's dv (the same size: same particles); the first step
    // starts from 0. Deterministic: the guess is the previous step's result.
    // Only a guess that beats 0 (|b - A dv_| < |b|): when the velocities shrink fast (a very
    // stiff, strongly damped step) the old dv is far larger than the new one, and CG would
    // reach the small answer as a difference of large numbers, losing its digits.
    if (dv_.size() != n) dv_.setZero(n);
    r_.noalias() = b - A_ * dv_;
    if (!(r_.squaredNorm() < b.squaredNorm())) dv_.setZero();
    Eigen::Index iterations = 0;
    double residual = 0.0;
    bool converged = false;
    const char* method = symmetric ? "conjugate gradients" : "BiCGSTAB";
    // One solve path for both Krylov methods (Eigen gives them the same interface).
    auto krylov = [&](auto& solver) {
      solver.setTolerance(1e-12);
      solver.setMaxIterations(max_iterations);
      solver.compute(A_);
      dv_ = solver.solveWithGuess(b, dv_);
      iterations = solver.iterations();
      residual = solver.error();
      converged = solver.info() == Eigen::Success;
    };
    if (symmetric) {
      krylov(cg_);
    } else {
      ++bicgstab_solves_;
      krylov(bicgstab_);
    }
    const double krylov_residual = residual;
    Eigen::VectorXd& dv = dv_;
    ++solves_;
    cg_iterations_ += static_cast<uint64_t>(iterations);
    cg_iterations_max_ = std::max(cg_iterations_max_, static_cast<uint64_t>(iterations));
    if (!converged) {
      spdlog::debug(
          "implicit_euler: {} stopped at residual {:.3g} after {} iterations; solving "
          "with sparse LU",
          method, krylov_residual, iterations);
      ++lu_fallbacks_;
      Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
      lu.compute(A_);
      const bool factored = lu.info() == Eigen::Success;
      if (factored) dv = lu.solve(b);
      const double bn = b.norm();
      residual = factored ? (A_ * dv - b).norm() / (bn > 0.0 ? bn : 1.0) : HUGE_VAL;
      if (!(residual <= 1e-8))
        throw NumericError(
            NumericError::Kind::SolverFailure,
            fmt::format("implicit_euler: the linear solve failed: {} stopped "
                        "at relative residual {:.3g} after {} iterations, and sparse LU {}{}",
                        method, krylov_residual, iterations,
                        factored ? fmt::format("left relative residual {:.3g}", residual)
                                 : std::string("could not factorize the system (singular?)"),
                        stiffness_text(sim, s, h)),
            sim.step_index() + 1, s.t, most_demanding(b, m), blame(sim, s, h));
    }
    check_accuracy(sim, s, b, dv, m, h);
    worst_residual_ = std::max(worst_residual_, residual);
    Eigen::Map<Eigen::VectorXd>(s.v.data(), n) += dv;
    sim.drift(s, h);
  }

  /// A = M - h D - h^2 K with the pinned rows and columns replaced by the identity, in the
  /// fixed sparsity pattern of A_: each entry the forces emit adds into its slot of A_'s
  /// values (found once, by pattern()), so a step sorts and allocates nothing. Also
  /// kv_ = K v0. The forces hand their entries (16 per spring, as 4 2x2 blocks) straight to
  /// a Scatter, which checks each one's position against the pattern's and adds it into its
  /// slot (and into K v0), in the order the forces emit them, each block's as its four
  /// entries row by row: the sums are the same bits as if every entry had come alone. Only
  /// if the positions or the pinned dofs differ from the pattern's (the first step, a force
  /// whose entries change) are the Jacobians asked for again, kept (JacobianEntries), and
  /// the pattern rebuilt from them.
  void assemble(Simulation& sim, const State& s, Eigen::Index n, double h,
                const Eigen::Map<const Eigen::VectorXd>& v0) {
    auto zero = [&] {
      ksum_.setZero();
      dsum_.setZero();
      kv_.setZero();
    };
    bool done = false;
    if (same_size_and_pins(n)) {
      zero();
      Scatter x{&px_, ksum_.data(), kv_.data(), v0.data(), n};
      Scatter v{&pv_, dsum_.data(), nullptr, nullptr, n};
      sim.jacobians(s, x.sink(), v.sink());
      done = x.complete() && v.complete();
    }
    if (!done) {
      sim.jacobian_entries(s, ex_, ev_);
      pattern(n);
      zero();
      Scatter x{&px_, ksum_.data(), kv_.data(), v0.data(), n};
      Scatter v{&pv_, dsum_.data(), nullptr, nullptr, n};
      x.feed(ex_);
      v.feed(ev_);
      ex_ = JacobianEntries();  // only the pattern's build needs them: free their memory
      ev_ = JacobianEntries();
    }
    double* a = A_.valuePtr();
    for (Eigen::Index j = 0; j < A_.nonZeros(); ++j) a[j] = (-h * dsum_[j]) - (h * h) * ksum_[j];
    for (Eigen::Index i = 0; i < n; ++i) a[diag_slot_[i]] += m_[i] > 0.0 ? m_[i] : 1.0;
  }

  /// Where one Jacobian's entries go in A_: per single entry its slot (-1: a pinned row or
  /// column) and position row * n + col; per 2x2 block (i, j) the slots of its two columns'
  /// first entries (rows 2i and 2i + 1 are adjacent slots of a column; -1: pinned) and its
  /// particles (uint64 i << 32 | j), as pattern() found them, in the order they came.
  struct Slots {
    std::vector<int64_t> single, key, block;
    std::vector<uint64_t> block_key;
  };

  /// A sink that adds each entry into `sum` by its slot in `p` (and K v0 into kv if kv),
  /// checking its position; after the first entry that differs from the pattern's it adds
  /// nothing more and complete() is false.
  struct Scatter {
    const Slots* p;
    double* sum;
    double* kv;
    const double* v0;
    Eigen::Index n;
    std::size_t k = 0, b = 0;  ///< single entries, blocks so far
    bool ok = true;

    bool complete() const { return ok && k == p->single.size() && b == p->block_key.size(); }
    void add(uint32_t row, uint32_t col, double value) {
      if (!ok || k >= p->single.size() ||
          p->key[k] != static_cast<int64_t>(row) * n + static_cast<int64_t>(col)) {
        ok = false;
        return;
      }
      if (p->single[k] >= 0) sum[p->single[k]] += value;
      if (kv) kv[row] += value * v0[col];
      ++k;
    }
    void add_block(uint64_t key, const double* v) {  // v column-major
      if (!ok || b >= p->block_key.size() || p->block_key[b] != key) {
        ok = false;
        return;
      }
      const int64_t s0 = p->block[2 * b], s1 = p->block[2 * b + 1];
      if (s0 >= 0) {
        sum[s0] += v[0];
        sum[s0 + 1] += v[1];
        sum[s1] += v[2];
        sum[s1 + 1] += v[3];
      }
      if (kv) {
        const std::size_t r = 2 * (key >> 32), c = 2 * (key & 0xffffffffu);
        kv[r] += v[0] * v0[c];  // row by row, as four single entries would
        kv[r] += v[2] * v0[c + 1];
        kv[r + 1] += v[1] * v0[c];
        kv[r + 1] += v[3] * v0[c + 1];
      }
      ++b;
    }
    /// Kept entries, in their order.
    void feed(const JacobianEntries& t) {
      std::size_t ks = 0, kb = 0;
      for (const JacobianEntries::Run& run : t.runs) {
        if (!run.block) {
          for (; ks < run.end; ++ks) {
            const Eigen::Triplet<double>& e = t.single[ks];
            add(static_cast<uint32_t>(e.row()), static_cast<uint32_t>(e.col()), e.value());
          }
          continue;
        }
        for (; kb < run.end; ++kb) add_block(t.blocks[kb], t.values.data() + 4 * kb);
      }
    }
    pinsim_triplet_sink sink() {
      return {this,
              [](void* c, uint32_t row, uint32_t col, double value) {
                static_cast<Scatter*>(c)->add(row, col, value);
              },
              [](void* c, const uint32_t* particles, const double* v, uint64_t count) {
                auto* self = static_cast<Scatter*>(c);
                for (uint64_t q = 0; q < count; ++q)
                  self->add_block(
                      static_cast<uint64_t>(particles[2 * q]) << 32 | particles[2 * q + 1],
                      v + 4 * q);
              }};
    }
  };

  /// Whether A_ is symmetric up to rounding: |a_ij - a_ji| <= 1e-13 (a_ii a_jj)^1/2 for
  /// every off-diagonal slot, compared with the slot of its transpose entry (tslot_, found by
  /// pattern(); -1 if the pattern lacks it: then the bound applies to a_ij alone). The
  /// entries of a symmetric Jacobian are sums whose order and rounding can differ between
  /// (i, j) and (j, i) by a few ulps of the diagonal; CG's product with A^T instead of A then
  /// errs by under 1e-13 of the Jacobi-scaled A per entry, the order of its own 1e-12
  /// tolerance. A real asymmetry (a turning damped spring) is far above that. A NaN fails.
  bool is_symmetric() const {
    const double* a = A_.valuePtr();
    const Eigen::Index n = A_.cols();
    for (Eigen::Index c = 0; c < n; ++c) {
      const double dc = std::abs(a[diag_slot_[static_cast<std::size_t>(c)]]);
      for (Eigen::Index j = A_.outerIndexPtr()[c]; j < A_.outerIndexPtr()[c + 1]; ++j) {
        const int64_t t = tslot_[static_cast<std::size_t>(j)];
        if (t >= 0 && t <= j) continue;  // the diagonal, or a pair seen from the other side
        const double dr = std::abs(a[diag_slot_[static_cast<std::size_t>(A_.innerIndexPtr()[j])]]);
        const double diff = t < 0 ? a[j] : a[j] - a[t];
        if (!(std::abs(diff) <= 1e-13 * std::sqrt(dr * dc))) return false;
      }
    }
    return true;
  }

  bool same_size_and_pins(Eigen::Index n) const {
    if (A_.rows() != n) return false;
    for (Eigen::Index i = 0; i < n; ++i)
      if ((m_[i] > 0.0) != free_[static_cast<std::size_t>(i)]) return false;
    return true;
  }

  void pattern(Eigen::Index n) {
    free_.assign(static_cast<std::size_t>(n), false);
    for (Eigen::Index i = 0; i < n; ++i) free_[static_cast<std::size_t>(i)] = m_[i] > 0.0;
    std::vector<Eigen::Triplet<double>> pat;
    pat.reserve(ex_.entries() + ev_.entries() + static_cast<std::size_t>(n));
    auto kept = [&](Eigen::Index r, Eigen::Index c) { return m_[r] > 0.0 && m_[c] > 0.0; };
    auto block_at = [](uint64_t key) {
      return std::pair<Eigen::Index, Eigen::Index>(
          static_cast<Eigen::Index>(2 * (key >> 32)),
          static_cast<Eigen::Index>(2 * (key & 0xffffffffu)));
    };
    for (const JacobianEntries* t : {&ex_, &ev_}) {
      for (const auto& e : t->single)
        if (kept(e.row(), e.col())) pat.emplace_back(e.row(), e.col(), 0.0);
      for (const uint64_t key : t->blocks) {
        const auto [r, c] = block_at(key);
        if (!kept(r, c)) continue;
        for (int i = 0; i < 2; ++i)
          for (int j = 0; j < 2; ++j) pat.emplace_back(r + i, c + j, 0.0);
      }
    }
    for (Eigen::Index i = 0; i < n; ++i) pat.emplace_back(i, i, 0.0);
    A_.resize(n, n);
    A_.setFromTriplets(pat.begin(), pat.end());
    A_.makeCompressed();
    auto slot = [&](Eigen::Index r, Eigen::Index c) -> int64_t {
      const int* first = A_.innerIndexPtr() + A_.outerIndexPtr()[c];
      const int* last = A_.innerIndexPtr() + A_.outerIndexPtr()[c + 1];
      return std::lower_bound(first, last, static_cast<int>(r)) - A_.innerIndexPtr();
    };
    auto slots = [&](const JacobianEntries& t, Slots& out) {
      out.single.resize(t.single.size());
      out.key.resize(t.single.size());
      for (std::size_t k = 0; k < t.single.size(); ++k) {
        const auto& e = t.single[k];
        out.single[k] = kept(e.row(), e.col()) ? slot(e.row(), e.col()) : -1;
        out.key[k] = e.row() * n + e.col();
      }
      out.block_key = t.blocks;
      out.block.resize(2 * t.blocks.size());
      for (std::size_t b = 0; b < t.blocks.size(); ++b) {
        const auto [r, c] = block_at(t.blocks[b]);
        const bool in = kept(r, c);
        out.block[2 * b] = in ? slot(r, c) : -1;  // (r + 1, c) is the next slot
        out.block[2 * b + 1] = in ? slot(r, c + 1) : -1;
      }
    };
    slots(ex_, px_);
    slots(ev_, pv_);
    diag_slot_.resize(static_cast<std::size_t>(n));
    for (Eigen::Index i = 0; i < n; ++i) diag_slot_[static_cast<std::size_t>(i)] = slot(i, i);
    // The slot of each slot's transpose entry (the pattern need not be symmetric).
    tslot_.resize(static_cast<std::size_t>(A_.nonZeros()));
    for (Eigen::Index c = 0; c < n; ++c)
      for (Eigen::Index j = A_.outerIndexPtr()[c]; j < A_.outerIndexPtr()[c + 1]; ++j) {
        const Eigen::Index r = A_.innerIndexPtr()[j];
        const int* first = A_.innerIndexPtr() + A_.outerIndexPtr()[r];
        const int* last = A_.innerIndexPtr() + A_.outerIndexPtr()[r + 1];
        const int* at = std::lower_bound(first, last, static_cast<int>(c));
        tslot_[static_cast<std::size_t>(j)] =
            at != last && *at == static_cast<int>(c) ? at - A_.innerIndexPtr() : -1;
      }
    ksum_.resize(A_.nonZeros());
    dsum_.resize(A_.nonZeros());
  }

  /// Refuses a solve whose velocity error bound (sum r_i^2 / m_i)^1/2 exceeds
  /// 1e-3 (|v_n|_M^2 + |dv|_M^2)^1/2 (see above).
  void check_accuracy(Simulation& sim, const State& s, const Eigen::VectorXd& b,
                      const Eigen::VectorXd& dv, const Eigen::VectorXd& m, double h) {
    const Eigen::VectorXd r = A_ * dv - b;
    double r2 = 0.0, v2 = 0.0, worst = 0.0;
    Eigen::Index at = -1;
    for (Eigen::Index i = 0; i < r.size(); ++i) {
      if (!(m[i] > 0.0)) continue;  // pinned: r_i = 0
      const double vi = s.v.data()[i];
      v2 += m[i] * (vi * vi + dv[i] * dv[i]);
      const double e = r[i] * r[i] / m[i];
      r2 += e;
      if (at < 0 || !(e <= worst)) {  // a NaN is the worst
        worst = e;
        at = i;
      }
    }
    if (r2 <= 1e-6 * v2) return;
    throw NumericError(
        NumericError::Kind::SolverFailure,
        fmt::format("implicit_euler: the linear solve cannot be trusted: its velocity error "
                    "bound (sum r_i^2 / m_i)^1/2 = {:.6g} exceeds 1e-3 x (|v|_M^2 + |dv|_M^2)^1/2 "
                    "= {:.6g} (the "
                    "system M - h df/dv - h^2 df/dx is too ill-conditioned for double "
                    "precision){}",
                    std::sqrt(r2), 1e-3 * std::sqrt(v2), stiffness_text(sim, s, h)),
        sim.step_index() + 1, s.t, at / 2, blame(sim, s, h));
  }

  /// The particle whose dofs ask for the largest velocity change |b_i| / m_i (a NaN first).
  static int64_t most_demanding(const Eigen::VectorXd& b, const Eigen::VectorXd& m) {
    Eigen::Index at = -1;
    double most = 0.0;
    for (Eigen::Index i = 0; i < b.size(); ++i) {
      if (!(m[i] > 0.0)) continue;
      const double d = std::abs(b[i]) / m[i];
      if (at < 0 || !(d <= most)) {
        most = d;
        at = i;
        if (std::isnan(d)) break;
      }
    }
    return at < 0 ? -1 : at / 2;
  }

  static std::string blame(Simulation& sim, const State& s, double h) {
    double w = 0.0;
    const int64_t k = sim.stiffest_force(s, h, w);
    return k < 0 ? std::string("integrator 'implicit_euler'")
                 : sim.force_label(static_cast<std::size_t>(k));
  }

  static std::string stiffness_text(Simulation& sim, const State& s, double h) {
    double w = 0.0;
    const int64_t k = sim.stiffest_force(s, h, w);
    if (k < 0) return "";
    return fmt::format("; stiffest force: {} ((h^2 |df/dx| + h |df/dv|) / m up to {:.6g})",
                       sim.force_label(static_cast<std::size_t>(k)), w);
  }

  nlohmann::json stats() const override {
    return {
        {"linear_solves", solves_},
        {"preconditioner", "jacobi"},
        {"warm_start", true},
        {"cg_iterations_per_solve",
         solves_ > 0 ? static_cast<double>(cg_iterations_) / static_cast<double>(solves_) : 0.0},
        {"cg_iterations_max", cg_iterations_max_},
        {"worst_relative_residual", worst_residual_},
        {"lu_fallbacks", lu_fallbacks_},
        {"bicgstab_solves", bicgstab_solves_}};
  }

 private:
  ImplicitEulerOptions options_;
  Eigen::VectorXd dv_;  ///< the last step's velocity change: the next solve's first guess
  uint64_t solves_ = 0, cg_iterations_ = 0, cg_iterations_max_ = 0, lu_fallbacks_ = 0,
           bicgstab_solves_ = 0;  ///< solves of a nonsymmetric A (BiCGSTAB, maybe then LU)
  double worst_residual_ = 0.0;
  Eigen::Matrix2Xd f_;
  JacobianEntries ex_, ev_;         ///< df/dx, df/dv entries (kept capacity)
  Eigen::VectorXd m_, kv_, b_, r_;  ///< masses (0: pinned), K v_n, right side
  // The pattern of A_: where each entry goes in A_'s values and the entries' positions it
  // was built for (Slots), the free dofs it was built for, each diagonal's slot.
  // tslot_: per slot of A_, the slot of its transpose entry (-1: not in the pattern).
  Slots px_, pv_;
  std::vector<int64_t> diag_slot_, tslot_;
  std::vector<bool> free_;
  Eigen::VectorXd ksum_, dsum_;  ///< per slot: sum of df/dx, of df/dv
  Eigen::SparseMatrix<double> A_;
  // CG for a symmetric A (it multiplies by A^T); BiCGSTAB for a nonsymmetric one.
  Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg_;
  Eigen::BiCGSTAB<Eigen::SparseMatrix<double>, Eigen::DiagonalPreconditioner<double>> bicgstab_;
};

}  // namespace

std::unique_ptr<Integrator> make_implicit_euler(const ImplicitEulerOptions& options) {
  return std::make_unique<ImplicitEuler>(options);
}

}  // namespace pinsim
