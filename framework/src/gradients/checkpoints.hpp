// Checkpointing for the adjoint of a run: the forward pass keeps the state every S steps;
// the backward pass replays each segment from its checkpoint, recording its S steps, and
// runs their adjoints in reverse. With S = ceil(sqrt(N)) it keeps about 2 sqrt(N) states
// and steps the run twice (Griewank & Walther, "Evaluating Derivatives", ch. 12: the
// two-level schedule; the uniform segments of NVIDIA Warp's fluid checkpoint example).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace pinsim::grad {

/// Uniform segments of `segment` steps over a run of `steps` steps.
struct CheckpointPlan {
  uint64_t steps = 0;
  uint64_t segment = 1;

  /// Segments of `segment` steps (0: ceil(sqrt(steps)), at least 1).
  static CheckpointPlan uniform(uint64_t steps, uint64_t segment = 0) {
    CheckpointPlan p;
    p.steps = steps;
    if (segment == 0) {
      segment = static_cast<uint64_t>(std::ceil(std::sqrt(static_cast<double>(steps))));
      while (segment > 1 && (segment - 1) * (segment - 1) >= steps) --segment;
      while (segment * segment < steps) ++segment;
    }
    p.segment = std::max<uint64_t>(segment, 1);
    return p;
  }
  uint64_t segments() const { return steps == 0 ? 0 : (steps + segment - 1) / segment; }
  /// The first step of segment k (the checkpoint's step index) and one past its last.
  uint64_t begin(uint64_t k) const { return k * segment; }
  uint64_t end(uint64_t k) const { return std::min(steps, (k + 1) * segment); }
  /// The most states held at once in the backward pass: the checkpoints and one segment's
  /// step records.
  uint64_t peak_records() const { return segments() + std::min(segment, steps); }
};

/// The forward pass: keeps save() (a C, the state to restart from) before each segment,
/// steps with step(nullptr) (a T* tape, null: no recording) and calls after(n) after step n
/// (1..N; loss terms). Returns the checkpoints, one per segment.
template <class C, class T, class Save, class Step, class After>
std::vector<C> forward_pass(const CheckpointPlan& plan, Save&& save, Step&& step, After&& after) {
  std::vector<C> checkpoints;
  checkpoints.reserve(plan.segments());
  for (uint64_t n = 0; n < plan.steps; ++n) {
    if (n % plan.segment == 0) checkpoints.push_back(save());
    step(static_cast<T*>(nullptr));
    after(n + 1);
  }
  return checkpoints;
}

/// The backward pass: per segment from the last, restore(checkpoint), the segment's steps
/// again with step(&tape) recording each, replayed(n) with the step index reached (to check
/// it against the forward pass), then back(n, tape) for n from the segment's last step to
/// its first: the adjoint of step n, from the adjoint after it to the one before it.
template <class C, class T, class Restore, class Step, class Back, class Replayed>
void backward_pass(const CheckpointPlan& plan, const std::vector<C>& checkpoints, Restore&& restore,
                   Step&& step, Back&& back, Replayed&& replayed) {
  std::vector<T> tapes(std::min(plan.segment, plan.steps));
  for (uint64_t k = plan.segments(); k-- > 0;) {
    restore(checkpoints[k]);
    const uint64_t b = plan.begin(k), e = plan.end(k);
    for (uint64_t n = b; n < e; ++n) step(&tapes[n - b]);
    replayed(e);
    for (uint64_t n = e; n-- > b;) back(n + 1, tapes[n - b]);
  }
}

}  // namespace pinsim::grad
