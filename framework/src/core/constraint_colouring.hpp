// Groups of constraints that share no moving particle (a greedy graph colouring of the
// constraints' topology), so the constraints of one group can be projected at the same time:
// each particle is written by at most one of them, and the result does not depend on how the
// group is split among threads.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/constraints.hpp"

namespace pinsim {

/// The colours: colour c holds the constraints order[start[c] .. start[c + 1]), in increasing
/// id.
struct ConstraintColouring {
  std::vector<uint32_t> order;
  std::vector<std::size_t> start{0};
  std::size_t colours() const { return start.size() - 1; }
};

/// Colours the constraints j with include[j] != 0, in id order, each with the smallest colour
/// that no earlier constraint sharing one of its particles has; particles with moves[i] == 0
/// (pinned: never written) do not count as shared. Fixed by the topology alone (never by the
/// thread count); greedy colouring uses at most (largest number of constraints a constraint
/// shares a particle with) + 1 colours.
ConstraintColouring colour_constraints(const ConstraintSystem& system,
                                       const std::vector<char>& include,
                                       const std::vector<char>& moves);

}  // namespace pinsim
