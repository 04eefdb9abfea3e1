// Jacobi-preconditioned conjugate gradients and BiCGSTAB on a BlockSparseMatrix2: the solves
// of implicit Euler's step and of its adjoint's transposed system. Deterministic: the row
// chunks depend on the particle count alone and every sum is summed per chunk, then over
// the chunks in order, so the same bits come out for any thread count.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "core/block_sparse_matrix.hpp"
#include "pinsim/parallel.hpp"

namespace pinsim {

/// The matrix of a linear system with what its solvers need: the index of each block row's
/// diagonal block (the Jacobi preconditioner) and, per block, the block of its transpose
/// (-1 where the pattern lacks it).
struct BlockSystem {
  BlockSparseMatrix2 a;
  std::vector<int64_t> diag_block, tblock;

  /// diag_block and tblock from a's pattern (once per pattern).
  void index();
  /// Whether the pattern holds every block's transpose (A and A^T share it).
  bool symmetric_pattern() const;
  /// Whether A is symmetric up to rounding: |a_ij - a_ji| <= 1e-13 |a_ii|^1/2 |a_jj|^1/2 for
  /// every off-diagonal entry (the bound on a_ij alone where the transpose block is missing);
  /// a NaN fails. `root` is scratch storage.
  bool is_symmetric(std::vector<double>& root) const;
  /// out = A^T (storage reused): in A's own pattern when it holds every block's transpose,
  /// else in the transposed pattern (out indexed afresh).
  void transpose_into(BlockSystem& out) const;
};

/// The solvers, with their vectors kept from solve to solve (no allocation per solve).
class BlockKrylov {
 public:
  struct Solve {
    Eigen::Index iterations = 0;
    double residual = 0.0;  ///< |r| / |b| of the iteration's own residual r
    bool converged = false;
  };

  /// Particle rows per chunk of the loops (up to 1024 particles, one chunk: the serial sums).
  static constexpr std::size_t kRows = 1024;

  /// Sizes the vectors for np particles (2 np unknowns).
  void resize(int64_t np);
  int64_t rows() const { return np_; }

  /// r = b - A x; returns |r|^2.
  double residual_of(const BlockSystem& s, const Eigen::VectorXd& b, const Eigen::VectorXd& x,
                     Eigen::VectorXd& r);
  /// Preconditioned conjugate gradients on A x = b from x, whose residual is r (Eigen's
  /// ConjugateGradient, same steps and stopping rule: |r|^2 < max(1e-24 |b|^2, min normal)),
  /// with A's product a gather by rows and the vector updates fused into three passes per
  /// iteration. bb = |b|^2. Converged: |r| <= 1e-12 |b|.
  Solve cg(const BlockSystem& s, double bb, Eigen::VectorXd& x, Eigen::VectorXd& r,
           Eigen::Index max_iterations);
  /// Right-preconditioned BiCGSTAB on A x = b from x, whose residual is r (Eigen's BiCGSTAB:
  /// same steps, restart when r drifts orthogonal to r0, stopping rule |r|^2 <= 1e-24 |b|^2;
  /// and, as van der Vorst's, it stops halfway through an iteration when the intermediate
  /// residual s already meets the rule).
  Solve bicgstab(const BlockSystem& s, const Eigen::VectorXd& b, double bb, Eigen::VectorXd& x,
                 Eigen::VectorXd& r, Eigen::Index max_iterations);

  /// Calls body(lo, hi) for each chunk of particle rows [lo, hi), on threads when there are
  /// enough (pinsim/parallel.hpp, Schedule::Even).
  template <class Body>
  void for_rows(Body&& body) const {
    for_chunks(
        static_cast<std::size_t>(np_), kRows,
        [&](std::size_t, std::size_t lo, std::size_t hi) {
          body(static_cast<int64_t>(lo), static_cast<int64_t>(hi));
        },
        Schedule::Even);
  }

  /// K sums over dofs, as for_rows: body(lo, hi, sum) adds dof i's term of sum k into
  /// sum[2k + (i & 1)] (or all into sum[2k]); returns per k the chunks' sum[2k] + sum[2k + 1]
  /// added in chunk order.
  template <std::size_t K, class Body>
  std::array<double, K> sum_rows(Body&& body) {
    const std::size_t chunks = chunk_count(static_cast<std::size_t>(np_), kRows);
    if (partial_.size() < 2 * K * chunks) partial_.resize(2 * K * chunks);
    double* part = partial_.data();
    for_chunks(
        static_cast<std::size_t>(np_), kRows,
        [&](std::size_t c, std::size_t lo, std::size_t hi) {
          double sum[2 * K] = {};
          body(static_cast<int64_t>(lo), static_cast<int64_t>(hi), sum);
          std::copy(sum, sum + 2 * K, part + 2 * K * c);
        },
        Schedule::Even);
    std::array<double, K> out{};
    for (std::size_t c = 0; c < chunks; ++c)
      for (std::size_t k = 0; k < K; ++k)
        out[k] += part[2 * K * c + 2 * k] + part[2 * K * c + 2 * k + 1];
    return out;
  }

 private:
  /// out = A in; returns w . out.
  double product(const BlockSystem& s, const double* in, double* out, const double* w);
  /// The Jacobi preconditioner: 1 / a_ii (1 where a_ii = 0), as Eigen's
  /// DiagonalPreconditioner.
  void jacobi(const BlockSystem& s);

  int64_t np_ = 0;
  Eigen::VectorXd r0_, p_, v_, y_, z_, s_, t_, inv_diag_;
  std::vector<double> partial_;  ///< sum_rows' per-chunk sums
};

}  // namespace pinsim
