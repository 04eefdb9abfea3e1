#include "core/constraint_colouring.hpp"

namespace pinsim {

ConstraintColouring colour_constraints(const ConstraintSystem& system,
                                       const std::vector<char>& include,
                                       const std::vector<char>& moves) {
  const std::size_t m = system.size();
  // used[i]: the colours of the constraints coloured so far on particle i
  std::vector<std::vector<uint32_t>> used(moves.size());
  std::vector<uint32_t> colour(m, 0);
  std::vector<std::size_t> stamp;  // stamp[c] == j + 1: colour c is taken by a neighbour of j
  std::size_t colours = 0;
  for (std::size_t j = 0; j < m; ++j) {
    if (include[j] == 0) continue;
    for (uint32_t i : system.particles(j))
      if (moves[i] != 0)
        for (uint32_t c : used[i]) stamp[c] = j + 1;
    uint32_t c = 0;
    while (c < colours && stamp[c] == j + 1) ++c;
    if (c == colours) {
      ++colours;
      stamp.push_back(0);
    }
    colour[j] = c;
    for (uint32_t i : system.particles(j))
      if (moves[i] != 0) used[i].push_back(c);
  }
  // counting sort by colour, ids increasing within each
  ConstraintColouring out;
  out.start.assign(colours + 1, 0);
  for (std::size_t j = 0; j < m; ++j)
    if (include[j] != 0) ++out.start[colour[j] + 1];
  for (std::size_t c = 0; c < colours; ++c) out.start[c + 1] += out.start[c];
  out.order.resize(out.start[colours]);
  std::vector<std::size_t> at(out.start.begin(), out.start.end() - 1);
  for (std::size_t j = 0; j < m; ++j)
    if (include[j] != 0) out.order[at[colour[j]]++] = static_cast<uint32_t>(j);
  return out;
}

}  // namespace pinsim
