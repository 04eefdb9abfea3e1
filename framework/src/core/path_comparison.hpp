// Two runs of one scene compared step by step, as a picture of a failed comparison shows
// them: every particle's path in the reference's run and in the other one (the grader's:
// the submission's), the step where the comparison failed and, if a particle's centre went
// into an obstacle, where. The grader fills it; pictures draws it (comparison_png).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/scene.hpp"

namespace pinsim {

struct PathComparison {
  using Path = std::vector<Eigen::Vector2d>;

  /// The scene as the reference ran it: its backend (the reference's) draws the table.
  Scene scene;
  /// Per particle, its positions from the start to step `drawn_to` in the reference's run
  /// and in the other, sampled at the same steps (every step, or every few on a long run;
  /// the start and the last step always).
  std::vector<Path> reference, mine;
  uint64_t drawn_to = 0;  ///< the paths' last step: the failing step, or a later one

  /// The step at which the comparison failed (counting from 1), its time (s), the particle
  /// it failed on, and where that particle was then in both runs (scene units).
  uint64_t step = 0;
  uint64_t steps = 0;  ///< steps of the whole run
  double t = 0.0;
  std::size_t particle = 0;
  Eigen::Vector2d mine_at = Eigen::Vector2d::Zero(), reference_at = Eigen::Vector2d::Zero();
  /// What happened at that step, for the caption.
  std::string what = "the test failed";

  /// Where a particle's centre first reached an obstacle along a step's straight path in the
  /// other run (a ball that tunnelled through a wall, or sank into it).
  struct Crossing {
    uint64_t step = 0;  ///< the step whose path reached it
    double t = 0.0;     ///< the time along that step, s
    std::size_t particle = 0;
    Eigen::Vector2d at = Eigen::Vector2d::Zero();
    std::string obstacle;  ///< the obstacle's id in the scene
  };
  std::optional<Crossing> crossing;
};

/// A comparison drawn: the PNG's bytes, its size in pixels, and one sentence saying what its
/// colours and marks are.
struct ComparisonPicture {
  std::string png;
  int width = 0, height = 0;
  std::string legend;
};

}  // namespace pinsim
