// A square sparse matrix of 2x2 blocks, one block row per particle (block compressed rows):
// implicit Euler's system matrix. Products gather (row by row, no scattered adds), and
// each row's sum runs over its blocks in column order: the same bits every call.
#pragma once

#include <Eigen/SparseCore>
#include <cstdint>
#include <vector>

namespace pinsim {

struct BlockSparseMatrix2 {
  /// Block row i holds the blocks first[i] .. first[i + 1] - 1, at block columns col[k]
  /// (increasing), with values value[4k .. 4k + 3] row-major (a00, a01, a10, a11).
  std::vector<int64_t> first{0};
  std::vector<int32_t> col;
  std::vector<double> value;

  /// Block rows (particles); the matrix has 2 rows() scalar rows.
  int64_t rows() const { return static_cast<int64_t>(first.size()) - 1; }
  int64_t blocks() const { return static_cast<int64_t>(col.size()); }

  /// The block (i, j)'s index, or -1 if the pattern lacks it.
  int64_t find(int64_t i, int64_t j) const {
    int64_t lo = first[static_cast<std::size_t>(i)], hi = first[static_cast<std::size_t>(i) + 1];
    while (lo < hi) {
      const int64_t mid = (lo + hi) / 2;
      if (col[static_cast<std::size_t>(mid)] < j)
        lo = mid + 1;
      else
        hi = mid;
    }
    return lo < first[static_cast<std::size_t>(i) + 1] && col[static_cast<std::size_t>(lo)] == j
               ? lo
               : -1;
  }

  /// Calls row(i, y0, y1) with (A x)_{2i}, (A x)_{2i+1} for each block row i in order.
  template <class Row>
  void multiply(const double* x, Row&& row) const {
    multiply(x, 0, rows(), row);
  }

  /// The same for the block rows lo .. hi - 1 only.
  template <class Row>
  void multiply(const double* x, int64_t lo, int64_t hi, Row&& row) const {
    const int64_t* f = first.data();
    const int32_t* c = col.data();
    const double* a = value.data();
    for (int64_t i = lo; i < hi; ++i) {
      double y0 = 0.0, y1 = 0.0;
      for (int64_t k = f[i]; k < f[i + 1]; ++k) {
        const double* b = a + 4 * k;
        const double* xj = x + 2 * static_cast<int64_t>(c[k]);
        y0 += b[0] * xj[0] + b[1] * xj[1];
        y1 += b[2] * xj[0] + b[3] * xj[1];
      }
      row(i, y0, y1);
    }
  }

  /// The same matrix as an Eigen sparse matrix (for the sparse LU fallback).
  Eigen::SparseMatrix<double> to_eigen() const {
    std::vector<Eigen::Triplet<double>> t;
    t.reserve(value.size());
    for (int64_t i = 0; i < rows(); ++i)
      for (int64_t k = first[static_cast<std::size_t>(i)];
           k < first[static_cast<std::size_t>(i) + 1]; ++k) {
        const int64_t j = col[static_cast<std::size_t>(k)];
        const double* b = value.data() + 4 * k;
        for (int r = 0; r < 2; ++r)
          for (int s = 0; s < 2; ++s)
            t.emplace_back(static_cast<int>(2 * i + r), static_cast<int>(2 * j + s), b[2 * r + s]);
      }
    Eigen::SparseMatrix<double> m(2 * rows(), 2 * rows());
    m.setFromTriplets(t.begin(), t.end());
    m.makeCompressed();
    return m;
  }
};

}  // namespace pinsim
