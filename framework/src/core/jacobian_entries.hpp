// Jacobian entries as the forces hand them over: single entries and 2x2 blocks, in order.
#pragma once

#include <pinsim/abi.h>

#include <Eigen/SparseCore>
#include <cstdint>
#include <vector>

namespace pinsim {

/// The entries of one Jacobian (df/dx or df/dv) as the forces emit them through a
/// pinsim_triplet_sink: single entries (add) and 2x2 blocks (add_blocks), kept apart but in
/// their emission order (`runs`), so a consumer that walks the runs adds them up in the same
/// order as if every block had been four add() calls (rows 2i, 2i+1 by 2j, 2j+1, row by row).
/// Capacity is kept across clear(): a caller that reuses one allocates nothing per step.
struct JacobianEntries {
  /// A stretch of entries of one kind: single[from .. end) or blocks[from .. end) where
  /// `from` is the previous run's end of the same kind (0 for the first).
  struct Run {
    bool block;
    std::size_t end;
  };
  std::vector<Eigen::Triplet<double>> single;  ///< entries added one at a time
  std::vector<uint64_t> blocks;                ///< per block (uint64 i << 32) | j, particles
  std::vector<double> values;                  ///< per block its 4 entries, column-major
  std::vector<Run> runs;

  void clear() {
    single.clear();
    blocks.clear();
    values.clear();
    runs.clear();
  }
  std::size_t entries() const { return single.size() + 4 * blocks.size(); }

  void add(uint32_t row, uint32_t col, double value) {
    if (runs.empty() || runs.back().block) runs.push_back({false, 0});
    single.emplace_back(static_cast<int>(row), static_cast<int>(col), value);
    runs.back().end = single.size();
  }
  void add_blocks(const uint32_t* particles, const double* v, uint64_t count) {
    if (count == 0) return;
    if (runs.empty() || !runs.back().block) runs.push_back({true, 0});
    for (uint64_t k = 0; k < count; ++k)
      blocks.push_back(static_cast<uint64_t>(particles[2 * k]) << 32 | particles[2 * k + 1]);
    values.insert(values.end(), v, v + 4 * count);
    runs.back().end = blocks.size();
  }

  /// A sink that adds into *this (valid while *this lives).
  pinsim_triplet_sink sink() {
    return {this,
            [](void* c, uint32_t row, uint32_t col, double value) {
              static_cast<JacobianEntries*>(c)->add(row, col, value);
            },
            [](void* c, const uint32_t* particles, const double* v, uint64_t count) {
              static_cast<JacobianEntries*>(c)->add_blocks(particles, v, count);
            }};
  }

  /// Every entry as a triplet, in emission order (a block as its four entries row by row).
  void append_triplets(std::vector<Eigen::Triplet<double>>& out) const {
    std::size_t s = 0, b = 0;
    for (const Run& r : runs) {
      if (!r.block) {
        out.insert(out.end(), single.begin() + static_cast<std::ptrdiff_t>(s),
                   single.begin() + static_cast<std::ptrdiff_t>(r.end));
        s = r.end;
        continue;
      }
      for (; b < r.end; ++b) {
        const int i = static_cast<int>(blocks[b] >> 32),
                  j = static_cast<int>(blocks[b] & 0xffffffffu);
        const double* v = values.data() + 4 * b;
        out.emplace_back(2 * i, 2 * j, v[0]);
        out.emplace_back(2 * i, 2 * j + 1, v[2]);
        out.emplace_back(2 * i + 1, 2 * j, v[1]);
        out.emplace_back(2 * i + 1, 2 * j + 1, v[3]);
      }
    }
  }
};

}  // namespace pinsim
