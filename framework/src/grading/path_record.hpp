// What the picture of a failed simulation or path test shows, collected while the check steps
// the submission's run beside the reference's: both paths (bounded in memory however long
// the run), the step where the check failed, and where a ball's centre went into an obstacle.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "core/path_comparison.hpp"
#include "core/plugin_instance.hpp"
#include "core/scene.hpp"

namespace pinsim::grading {

class PathRecorder {
 public:
  /// Starts both paths at the initial positions of `reference_scene` (the scene as the
  /// reference runs it; its backend later draws the table).
  explicit PathRecorder(const Scene& reference_scene);

  /// Both runs after step n (n = 1, 2, ... in order).
  void add(uint64_t n, const State& mine, const State& reference);

  /// The comparison of a check that failed on `particle` at the last step added. With
  /// `table` (the reference's backend, if it has distance()) it also finds the first step,
  /// among the last ones, along whose straight path a centre reached an obstacle.
  PathComparison failed(std::size_t particle, const BackendInstance* table) const;

 private:
  /// Keeps every `stride_`-th step; past kMaxSamples samples, every other one is dropped and
  /// the stride doubles.
  void keep(const State& mine, const State& reference);

  PathComparison base_;
  std::size_t stride_ = 1;
  uint64_t last_step_ = 0;
  Eigen::Matrix2Xd last_mine_, last_reference_;
  double last_t_ = 0.0;
  /// The other run's positions at the last steps, every step (for the crossing search).
  struct Recent {
    uint64_t step;
    double t;
    Eigen::Matrix2Xd x;
  };
  std::deque<Recent> recent_;
  Eigen::VectorXd radius_;
  double dt_ = 0.0;
};

/// The caption beside the picture: what the colours and marks are, with the failing step,
/// its time and the positions, and where a ball went into which obstacle.
std::string comparison_caption(const PathComparison& c);

}  // namespace pinsim::grading
