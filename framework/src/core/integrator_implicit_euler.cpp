// Linearized backward Euler (Baraff & Witkin 1998, "Large steps in cloth simulation", eq. 6).
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <Eigen/SparseLU>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <utility>
#include <vector>

#include "core/block_krylov.hpp"
#include "core/integrators.hpp"
#include "core/simulation.hpp"
#include "core/step_context.hpp"
#include "pinsim/parallel.hpp"

namespace pinsim {
namespace {

/// Backward Euler v_{n+1} = v_n + h M^-1 f(x_{n+1}, v_{n+1}), x_{n+1} = x_n + h v_{n+1},
/// linearized once about (x_n, v_n) with K = df/dx, D = df/dv:
///   (M - h D - h^2 K) dv = h (f_n + h K v_n),   v_{n+1} = v_n + dv,
/// then the backend drifts x with v_{n+1}. Exact backward Euler for linear forces: on the
/// harmonic oscillator the energy shrinks by exactly 1/(1 + (h w)^2) per step, for any h.
/// Pinned dofs (inv_mass 0) keep dv = 0: their rows and columns become the identity.
/// A is symmetric for conservative forces, but not always: a damped spring's df/dx has the
/// nonsymmetric term -kd J^T (H v)^T when the spring turns; conjugate gradients on such a system
/// would converge to something else than A^-1 b (Eigen's ConjugateGradient with Lower|Upper
/// multiplies by A^T). Each step therefore checks A's symmetry up to rounding (every entry against
/// its transpose entry, whose block is found once with the pattern; see BlockSystem::is_symmetric)
/// and solves a symmetric A by conjugate gradients, a nonsymmetric one by BiCGSTAB, both with a
/// Jacobi (diagonal) preconditioner to a relative residual of 1e-12, started from the last step's
/// dv (warm start: a smooth motion changes dv little from step to step) when that guess's residual
/// is below |b|, else from 0. Both are written in core/block_krylov.cpp (Eigen's steps and stopping
/// rules) over A stored as 2x2 blocks by rows (BlockSparseMatrix2: products gather, no scattered
/// writes), with the vector updates fused into the products and a few passes per iteration, and the
/// warm start's residual as their first. A is assembled in a block pattern built once (rebuilt only
/// if the forces' entries move): no sorting or allocation per step; if the iterative solve fails
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
class ImplicitEuler : public Integrator, public LinearSystemStep {
 public:
  explicit ImplicitEuler(const ImplicitEulerOptions& o) : options_(o) {}

  Kick before_drift(StepContext& ctx, double h) override {
    solved_ = false;  // until this step's solve succeeds (a step that throws leaves none)
    State& s = ctx.state();
    ctx.compute_forces(s, f_);
    const Eigen::Index n = 2 * static_cast<Eigen::Index>(s.size());
    const Eigen::Map<const Eigen::VectorXd> v0(s.v.data(), n);

    if (m_.size() != n) m_.resize(n);
    krylov_.resize(n / 2);
    for_rows([&](int64_t lo, int64_t hi) {
      for (int64_t i = 2 * lo; i < 2 * hi; ++i) {
        const double w = s.inv_mass[i / 2];
        m_[i] = w > 0.0 ? 1.0 / w : 0.0;
      }
    });
    const Eigen::VectorXd& m = m_;
    // A, and K v_n straight from the entries; b = h (f_n + h K v_n), pinned rows zeroed.
    if (kv_.size() != n) kv_.resize(n);
    assemble(ctx, s, n, h, v0);
    for (Eigen::VectorXd* x : {&b_, &r_})
      if (x->size() != n) x->resize(n);
    const double* f = f_.data();
    const double bb = sum_rows<1>([&](int64_t lo, int64_t hi, double* sum) {
      for (int64_t i = 2 * lo; i < 2 * hi; ++i) {
        b_[i] = m[i] > 0.0 ? h * (f[i] + h * kv_[i]) : 0.0;
        sum[0] += b_[i] * b_[i];
      }
    })[0];
    const Eigen::VectorXd& b = b_;
    const bool symmetric = sys_.is_symmetric(root_diag_);
    solved_symmetric_ = symmetric;
    const Eigen::Index max_iterations = options_.cg_max_iterations > 0
                                            ? options_.cg_max_iterations
                                            : std::max<Eigen::Index>(100, 4 * n);
    // Warm start from the last step's dv (the same size: same particles); the first step
    // starts from 0. Deterministic: the guess is the previous step's result.
    // Only a guess that beats 0 (|b - A dv_| < |b|): when the velocities shrink fast (a very
    // stiff, strongly damped step) the old dv is far larger than the new one, and CG would
    // reach the small answer as a difference of large numbers, losing its digits.
    // The guess's residual is the Krylov solve's first residual.
    if (dv_.size() != n) dv_.setZero(n);
    const double rr = residual_of(dv_, r_);
    if (!(rr < bb)) {
      dv_.setZero();
      r_ = b;
    }
    BlockKrylov::Solve out;
    const char* method = symmetric ? "conjugate gradients" : "BiCGSTAB";
    if (symmetric) {
      out = krylov_.cg(sys_, bb, dv_, r_, max_iterations);
    } else {
      ++bicgstab_solves_;
      out = krylov_.bicgstab(sys_, b_, bb, dv_, r_, max_iterations);
    }
    Eigen::Index iterations = out.iterations;
    double residual = out.residual;
    const double krylov_residual = residual;
    Eigen::VectorXd& dv = dv_;
    ++solves_;
    cg_iterations_ += static_cast<uint64_t>(iterations);
    cg_iterations_max_ = std::max(cg_iterations_max_, static_cast<uint64_t>(iterations));
    if (!out.converged) {
      spdlog::debug(
          "implicit_euler: {} stopped at residual {:.3g} after {} iterations; solving "
          "with sparse LU",
          method, krylov_residual, iterations);
      ++lu_fallbacks_;
      const Eigen::SparseMatrix<double> a = sys_.a.to_eigen();
      Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
      lu.compute(a);
      const bool factored = lu.info() == Eigen::Success;
      if (factored) dv = lu.solve(b);
      const double bn = b.norm();
      residual = factored ? (a * dv - b).norm() / (bn > 0.0 ? bn : 1.0) : HUGE_VAL;
      if (!(residual <= 1e-8))
        throw NumericError(
            NumericError::Kind::SolverFailure,
            fmt::format("implicit_euler: the linear solve failed: {} stopped "
                        "at relative residual {:.3g} after {} iterations, and sparse LU {}{}",
                        method, krylov_residual, iterations,
                        factored ? fmt::format("left relative residual {:.3g}", residual)
                                 : std::string("could not factorize the system (singular?)"),
                        stiffness_text(ctx, s, h)),
            ctx.step(), s.t, most_demanding(b, m), blame(ctx, s, h));
    }
    solved_ = true;
    check_accuracy(ctx, s, b, dv, m, h);
    worst_residual_ = std::max(worst_residual_, residual);
    Eigen::Map<Eigen::VectorXd>(s.v.data(), n) += dv;
    return {};  // the drift moves with v_{n+1} and ends the step
  }

  /// r = b_ - A x; returns |r|^2.
  double residual_of(const Eigen::VectorXd& x, Eigen::VectorXd& r) {
    return krylov_.residual_of(sys_, b_, x, r);
  }

  static constexpr std::size_t kRows = BlockKrylov::kRows;
  template <class Body>
  void for_rows(Body&& body) const {
    krylov_.for_rows(body);
  }
  template <std::size_t K, class Body>
  std::array<double, K> sum_rows(Body&& body) {
    return krylov_.template sum_rows<K>(body);
  }

  /// A = M - h D - h^2 K with the pinned rows and columns replaced by the identity, in the fixed
  /// block pattern of sys_.a: A starts as M (the identity for pinned particles) and each entry the
  /// forces emit adds, times -h^2 (df/dx) or -h (df/dv), into its place in A's values (found once,
  /// by pattern()), so a step sorts and allocates nothing. Also kv_ = K v0. The forces hand their
  /// entries (16 per spring, as 4 2x2 blocks) straight to a Scatter, which checks each one's
  /// position against the pattern's and adds it into its place (and into K v0, a block's row times
  /// v0 at a time), in the order the forces emit them: the same sums in the same order every step,
  /// whether the entries come streamed or kept (JacobianEntries, the pattern's first step). Only if
  /// the positions or the pinned dofs differ from the pattern's (the first step, a force whose
  /// entries change) are the Jacobians asked for again, kept (JacobianEntries), and the pattern
  /// rebuilt from them.
  void assemble(StepContext& ctx, const State& s, Eigen::Index n, double h,
                const Eigen::Map<const Eigen::VectorXd>& v0) {
    auto start = [&] {
      for_rows([&](int64_t lo, int64_t hi) {
        const auto at = [&](int64_t i) { return sys_.a.value.begin() + 4 * sys_.a.first[i]; };
        std::fill(at(lo), at(hi), 0.0);
        for (int64_t i = lo; i < hi; ++i) {
          double* d = sys_.a.value.data() + 4 * sys_.diag_block[static_cast<std::size_t>(i)];
          d[0] = m_[2 * i] > 0.0 ? m_[2 * i] : 1.0;
          d[3] = m_[2 * i + 1] > 0.0 ? m_[2 * i + 1] : 1.0;
          kv_[2 * i] = kv_[2 * i + 1] = 0.0;
        }
      });
    };
    const std::size_t forces = ctx.forces().size();
    bool done = false;
    if (same_size_and_pins(n) && px_.size() == forces) {
      start();
      done = scatter_groups(n, h, v0, [&](std::size_t k, Scatter& x, Scatter& v) {
        ctx.jacobians(k, s, x.sink(), v.sink());
      });
      ctx.count_jacobian_evaluation();
    }
    if (!done) {
      ex_.resize(forces);
      ev_.resize(forces);
      for (std::size_t k = 0; k < forces; ++k) {
        ex_[k].clear();
        ev_[k].clear();
        ctx.jacobians(k, s, ex_[k].sink(), ev_[k].sink());
      }
      ctx.count_jacobian_evaluation();
      pattern(n, ctx);
      ++pattern_builds_;
      start();
      scatter_groups(n, h, v0, [&](std::size_t k, Scatter& x, Scatter& v) {
        x.feed(ex_[k]);
        v.feed(ev_[k]);
      });
      ex_.clear();  // only the pattern's build needs them: free their memory
      ev_.clear();
    }
  }

  /// Adds every force's entries into A (already M) and kv_ (already 0), fill(k, x, v)
  /// handing force k's entries to its Scatters. The forces go in groups (pattern()): group
  /// 0, every force not in a group of its own in scene order, into A itself; each other
  /// group, one concurrent() force with many entries, into its own zeroed copy of A's values
  /// and of kv (on another thread when there is one: the plugin contract lets two such
  /// forces run at once), added to A and kv_ afterwards, group by group. The groups depend
  /// on the forces and their entries only, so the sums, and the bits, are the same for any
  /// thread count. Returns whether every force's entries matched the pattern.
  template <class Fill>
  bool scatter_groups(Eigen::Index n, double h, const Eigen::Map<const Eigen::VectorXd>& v0,
                      Fill&& fill) {
    const std::size_t groups = 1 + own_.size();
    if (complete_.size() != px_.size()) complete_.assign(px_.size(), 0);
    errors_.assign(px_.size(), nullptr);
    for_chunks(groups, 1, [&](std::size_t g, std::size_t, std::size_t) {
      double* a = sys_.a.value.data();
      double* kv = kv_.data();
      if (g > 0) {
        std::vector<double>& values = own_[g - 1].values;
        Eigen::VectorXd& own_kv = own_[g - 1].kv;
        values.assign(sys_.a.value.size(), 0.0);
        own_kv.setZero(n);
        a = values.data();
        kv = own_kv.data();
      }
      for (std::size_t k = 0; k < px_.size(); ++k) {
        if (group_[k] != g) continue;
        Scatter x{&px_[k], a, -h * h, kv, v0.data(), n};
        Scatter v{&pv_[k], a, -h, nullptr, nullptr, n};
        try {
          fill(k, x, v);
        } catch (...) {  // this group stops here; every group runs, whatever the threads
          errors_[k] = std::current_exception();
          break;
        }
        complete_[k] = x.complete() && v.complete();
      }
    });
    // A plugin's failure: the first failing force in scene order, for any thread count.
    for (const std::exception_ptr& e : errors_)
      if (e) std::rethrow_exception(e);
    for (const char c : complete_)
      if (!c) return false;
    if (groups == 1) return true;
    for_rows([&](int64_t lo, int64_t hi) {
      const std::size_t b = 4 *
                            static_cast<std::size_t>(sys_.a.first[static_cast<std::size_t>(lo)]),
                        e = 4 *
                            static_cast<std::size_t>(sys_.a.first[static_cast<std::size_t>(hi)]);
      for (const OwnGroup& o : own_) {
        for (std::size_t q = b; q < e; ++q) sys_.a.value[q] += o.values[q];
        for (int64_t i = 2 * lo; i < 2 * hi; ++i) kv_[i] += o.kv[i];
      }
    });
    return true;
  }

  /// Where one Jacobian's entries go in A's values: per single entry its value's index
  /// (-1: a pinned row or column) and position row * n + col; per 2x2 block its block's
  /// index in A (-1: pinned) and its particles (uint64 i << 32 | j), as pattern() found
  /// them, in the order they came.
  struct Slots {
    std::vector<int64_t> single, key, block;
    std::vector<uint64_t> block_key;
  };

  /// A sink that adds each entry times `scale` into `a` by its place in `p` (and K v0 into
  /// kv if kv), checking its position; after the first entry that differs from the pattern's
  /// it adds nothing more and complete() is false.
  struct Scatter {
    const Slots* p;
    double* a;
    double scale;
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
      if (p->single[k] >= 0) a[p->single[k]] += scale * value;
      if (kv) kv[row] += value * v0[col];
      ++k;
    }
    void add_block(uint64_t key, const double* v) {  // v column-major, A's blocks row-major
      if (!ok || b >= p->block_key.size() || p->block_key[b] != key) {
        ok = false;
        return;
      }
      const int64_t s = p->block[b];
      if (s >= 0) {
        double* q = a + 4 * s;
        q[0] += scale * v[0];
        q[1] += scale * v[2];
        q[2] += scale * v[1];
        q[3] += scale * v[3];
      }
      if (kv) {
        const std::size_t r = 2 * (key >> 32), c = 2 * (key & 0xffffffffu);
        kv[r] += v[0] * v0[c] + v[2] * v0[c + 1];  // the block's row times v0, then added
        kv[r + 1] += v[1] * v0[c] + v[3] * v0[c + 1];
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
                Scatter self = *static_cast<Scatter*>(c);  // in registers, not through c
                for (uint64_t q = 0; q < count; ++q)
                  self.add_block(
                      static_cast<uint64_t>(particles[2 * q]) << 32 | particles[2 * q + 1],
                      v + 4 * q);
                *static_cast<Scatter*>(c) = self;
              }};
    }
  };

  bool same_size_and_pins(Eigen::Index n) const {
    if (2 * sys_.a.rows() != n) return false;
    for (Eigen::Index i = 0; i < n; ++i)
      if ((m_[i] > 0.0) != free_[static_cast<std::size_t>(i)]) return false;
    return true;
  }

  void pattern(Eigen::Index n, const StepContext& ctx) {
    free_.assign(static_cast<std::size_t>(n), false);
    for (Eigen::Index i = 0; i < n; ++i) free_[static_cast<std::size_t>(i)] = m_[i] > 0.0;
    auto kept = [&](Eigen::Index r, Eigen::Index c) { return m_[r] > 0.0 && m_[c] > 0.0; };
    const int64_t np = n / 2;
    std::vector<uint64_t> keys;  // blocks (i << 32 | j)
    // force k's Jacobian items (2x2 blocks and single entries, both matrices)
    auto items = [&](std::size_t k) {
      return ex_[k].blocks.size() + ev_[k].blocks.size() + ex_[k].single.size() +
             ev_[k].single.size();
    };
    std::size_t total = static_cast<std::size_t>(np);
    for (std::size_t k = 0; k < ex_.size(); ++k) total += items(k);
    keys.reserve(total);
    std::vector<const JacobianEntries*> all;
    for (std::size_t k = 0; k < ex_.size(); ++k) all.insert(all.end(), {&ex_[k], &ev_[k]});
    for (const JacobianEntries* t : all) {
      for (const auto& e : t->single)
        if (kept(e.row(), e.col()))
          keys.push_back(static_cast<uint64_t>(e.row() / 2) << 32 |
                         static_cast<uint64_t>(e.col() / 2));
      for (const uint64_t key : t->blocks)
        if (kept(static_cast<Eigen::Index>(2 * (key >> 32)),
                 static_cast<Eigen::Index>(2 * (key & 0xffffffffu))))
          keys.push_back(key);
    }
    for (int64_t i = 0; i < np; ++i)
      keys.push_back(static_cast<uint64_t>(i) << 32 | static_cast<uint64_t>(i));
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
    sys_.a.first.assign(static_cast<std::size_t>(np) + 1, 0);
    sys_.a.col.resize(keys.size());
    for (std::size_t k = 0; k < keys.size(); ++k) {
      ++sys_.a.first[(keys[k] >> 32) + 1];
      sys_.a.col[k] = static_cast<int32_t>(keys[k] & 0xffffffffu);
    }
    for (int64_t i = 0; i < np; ++i)
      sys_.a.first[static_cast<std::size_t>(i) + 1] += sys_.a.first[static_cast<std::size_t>(i)];
    sys_.a.value.assign(4 * keys.size(), 0.0);
    auto slots = [&](const JacobianEntries& t, Slots& out) {
      out.single.resize(t.single.size());
      out.key.resize(t.single.size());
      for (std::size_t k = 0; k < t.single.size(); ++k) {
        const auto& e = t.single[k];
        out.single[k] = kept(e.row(), e.col()) ? 4 * sys_.a.find(e.row() / 2, e.col() / 2) +
                                                     2 * (e.row() % 2) + (e.col() % 2)
                                               : -1;
        out.key[k] = e.row() * n + e.col();
      }
      out.block_key = t.blocks;
      out.block.resize(t.blocks.size());
      for (std::size_t b = 0; b < t.blocks.size(); ++b) {
        const int64_t i = static_cast<int64_t>(t.blocks[b] >> 32),
                      j = static_cast<int64_t>(t.blocks[b] & 0xffffffffu);
        out.block[b] = kept(2 * i, 2 * j) ? sys_.a.find(i, j) : -1;
      }
    };
    px_.resize(ex_.size());
    pv_.resize(ex_.size());
    group_.assign(ex_.size(), 0);
    std::size_t own = 0;
    bool first = true;  // the first concurrent force with many entries stays in group 0
    for (std::size_t k = 0; k < ex_.size(); ++k) {
      slots(ex_[k], px_[k]);
      slots(ev_[k], pv_[k]);
      if (!ctx.forces()[k]->concurrent() || items(k) < options_.own_group_entries) continue;
      if (first) {
        first = false;
        continue;
      }
      group_[k] = ++own;
    }
    own_.resize(own);
    sys_.index();
  }

  /// Refuses a solve whose velocity error bound (sum r_i^2 / m_i)^1/2 exceeds
  /// 1e-3 (|v_n|_M^2 + |dv|_M^2)^1/2 (see above), with r = A dv - b computed afresh (not the
  /// Krylov iteration's own residual, which rounding can make drift from it).
  void check_accuracy(StepContext& ctx, const State& s, const Eigen::VectorXd& b,
                      const Eigen::VectorXd& dv, const Eigen::VectorXd& m, double h) {
    const double* vel = s.v.data();
    // Per chunk of rows: the sums, and the dof with the largest r_i^2 / m_i (a NaN is the
    // worst) in worst_[2 c] (its value) and worst_[2 c + 1] (the dof, -1: none).
    const std::size_t chunks = chunk_count(static_cast<std::size_t>(krylov_.rows()), kRows);
    if (worst_.size() < 2 * chunks) worst_.resize(2 * chunks);
    const auto sums = sum_rows<2>([&](int64_t lo, int64_t hi, double* sum) {
      double worst = 0.0;
      Eigen::Index at = -1;
      auto dof = [&](Eigen::Index i, double y) {
        if (!(m[i] > 0.0)) return;  // pinned: r_i = 0
        const double ri = y - b[i];
        const double vi = vel[i];
        sum[2] += m[i] * (vi * vi + dv[i] * dv[i]);
        const double e = ri * ri / m[i];
        sum[0] += e;
        if (replaces(e, worst, at < 0)) {
          worst = e;
          at = i;
        }
      };
      sys_.a.multiply(dv.data(), lo, hi, [&](int64_t i, double y0, double y1) {
        dof(2 * i, y0);
        dof(2 * i + 1, y1);
      });
      const std::size_t c = static_cast<std::size_t>(lo) / kRows;
      worst_[2 * c] = worst;
      worst_[2 * c + 1] = static_cast<double>(at);
    });
    const double r2 = sums[0], v2 = sums[1];
    if (r2 <= 1e-6 * v2) return;
    double worst = 0.0;
    Eigen::Index at = -1;
    for (std::size_t c = 0; c < chunks; ++c)
      if (worst_[2 * c + 1] >= 0.0 && replaces(worst_[2 * c], worst, at < 0)) {
        worst = worst_[2 * c];
        at = static_cast<Eigen::Index>(worst_[2 * c + 1]);
      }
    throw NumericError(
        NumericError::Kind::SolverFailure,
        fmt::format("implicit_euler: the linear solve cannot be trusted: its velocity error "
                    "bound (sum r_i^2 / m_i)^1/2 = {:.6g} exceeds 1e-3 x (|v|_M^2 + |dv|_M^2)^1/2 "
                    "= {:.6g} (the "
                    "system M - h df/dv - h^2 df/dx is too ill-conditioned for double "
                    "precision){}",
                    std::sqrt(r2), 1e-3 * std::sqrt(v2), stiffness_text(ctx, s, h)),
        ctx.step(), s.t, at / 2, blame(ctx, s, h));
  }

  /// Whether e takes the worst dof's place (none yet: `none`): larger, and the first NaN
  /// stays the worst.
  static bool replaces(double e, double worst, bool none) {
    return none || (!std::isnan(worst) && !(e <= worst));
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

  static std::string blame(StepContext& ctx, const State& s, double h) {
    double w = 0.0;
    const std::string k = ctx.stiffest_force(s, h, w);
    return k.empty() ? std::string("integrator 'implicit_euler'") : k;
  }

  static std::string stiffness_text(StepContext& ctx, const State& s, double h) {
    double w = 0.0;
    const std::string k = ctx.stiffest_force(s, h, w);
    if (k.empty()) return "";
    return fmt::format("; stiffest force: {} ((h^2 |df/dx| + h |df/dv|) / m up to {:.6g})", k, w);
  }

  bool last_system_transposed(BlockSystem& out, bool& symmetric) const override {
    if (!solved_) return false;
    sys_.transpose_into(out);
    symmetric = solved_symmetric_;
    return true;
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
        {"bicgstab_solves", bicgstab_solves_},
        {"assembly_groups", 1 + own_.size()},
        {"pattern_builds", pattern_builds_}};
  }

 private:
  ImplicitEulerOptions options_;
  Eigen::VectorXd dv_;  ///< the last step's velocity change: the next solve's first guess
  uint64_t solves_ = 0, cg_iterations_ = 0, cg_iterations_max_ = 0, lu_fallbacks_ = 0,
           bicgstab_solves_ = 0;  ///< solves of a nonsymmetric A (BiCGSTAB, maybe then LU)
  double worst_residual_ = 0.0;
  Eigen::Matrix2Xd f_;
  std::vector<JacobianEntries> ex_, ev_;  ///< per force: df/dx, df/dv entries (pattern build)
  Eigen::VectorXd m_, kv_, b_, r_;        ///< masses (0: pinned), K v_n, right side, residual
  // The pattern of A: where each entry goes in A's values and the entries' positions it
  // was built for (Slots), the free dofs it was built for.
  std::vector<Slots> px_, pv_;  ///< per force
  /// Per force its group (scatter_groups): 0, or g >= 1 for own_[g - 1].
  std::vector<std::size_t> group_;
  struct OwnGroup {
    std::vector<double> values;  ///< its forces' share of A's values
    Eigen::VectorXd kv;          ///< and of K v0
  };
  std::vector<OwnGroup> own_;
  std::vector<char> complete_;              ///< per force: its entries matched the pattern
  std::vector<std::exception_ptr> errors_;  ///< per force: what its Jacobians threw
  uint64_t pattern_builds_ = 0;             ///< pattern() calls (stats)
  std::vector<double> root_diag_;           ///< |a_ii|^1/2 (BlockSystem::is_symmetric)
  std::vector<double> worst_;               ///< check_accuracy's per-chunk worst dof
  std::vector<bool> free_;
  BlockSystem sys_;                ///< A, its diagonal blocks and transposes
  bool solved_ = false;            ///< the last step solved sys_ (last_system_transposed)
  bool solved_symmetric_ = false;  ///< and found it symmetric
  BlockKrylov krylov_;             ///< the solves (and their vectors)
};

}  // namespace

std::unique_ptr<Integrator> make_implicit_euler(const ImplicitEulerOptions& options) {
  return std::make_unique<ImplicitEuler>(options);
}

}  // namespace pinsim
