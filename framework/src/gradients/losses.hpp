// Scalar losses of a run: sums of terms at step ends, each a function of the state then.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <pinsim/state.hpp>
#include <string>
#include <vector>

namespace pinsim::grad {

/// L = sum over steps n in 0..N of l_n(state after step n).
class Loss {
 public:
  virtual ~Loss() = default;
  /// Whether l_n is not identically zero.
  virtual bool has_term(uint64_t n) const = 0;
  /// l_n(s); adds d l_n / d x to gx and d l_n / d v to gv (2xN).
  virtual double term(uint64_t n, const State& s, Eigen::Matrix2Xd& gx,
                      Eigen::Matrix2Xd& gv) const = 0;
  /// One line: what it is, for gradient.json and messages.
  virtual std::string describe() const = 0;
};

/// Positions recorded at some steps (a run folder's trajectory), for a misfit.
struct RecordedFrames {
  std::string source;                      ///< the run folder, for messages
  std::vector<uint64_t> steps;             ///< step index of each frame, increasing
  std::vector<Eigen::Matrix2Xd> x;         ///< per frame, positions (columns = particles)
  std::vector<std::vector<bool>> present;  ///< per frame, which particles it has
};

/// How a loss specification is read (the run it applies to).
struct LossContext {
  uint64_t steps = 0;  ///< N
  double dt = 0.0;     ///< s
  std::size_t particles = 0;
};

/// Parses `spec`:
///   final:I:C          the final coordinate C (x, y, vx, vy) of particle I;
///   target:I:X,Y[@T]   |x_I(T) - (X, Y)|^2 at time T (a step time; default: the end).
/// Throws InputError naming the spec and what was expected (misfit losses come from
/// make_misfit, as they need a recorded run).
std::unique_ptr<Loss> parse_loss(const std::string& spec, const LossContext& ctx);

/// sum over frames f, particles i in the frame of |x_i(t_f) - x_rec,i(t_f)|^2. Throws
/// InputError if a frame's step is past the run or a frame has more particles than the run.
std::unique_ptr<Loss> make_misfit(RecordedFrames frames, const LossContext& ctx);

/// The step index of time t: round(t / dt), if t is within 1e-9 (relative) of it; else -1.
int64_t step_of_time(double t, double dt);

}  // namespace pinsim::grad
