#include "grading/path_record.hpp"

#include <algorithm>
#include <cmath>

#include "core/format.hpp"

namespace pinsim::grading {
namespace {

/// Samples kept per path before they are thinned: enough for a smooth line at any picture
/// size the grader draws, and a bounded memory on a run of any length.
constexpr std::size_t kMaxSamples = 4096;
/// Steps searched back from the failure for a centre that reached an obstacle: a path check
/// fails within a step or two of a tunnelling ball (its path jumps to the wall's far side).
constexpr std::size_t kRecentSteps = 64;
/// Sphere-tracing iterations along one step's path.
constexpr int kTraceIterations = 4096;

std::string point(const Eigen::Vector2d& p) {
  std::string s = "(";  // not "(" + num(...): GCC 12's -Wrestrict misfires on it
  s += num(p.x(), 6);
  s += ", ";
  s += num(p.y(), 6);
  s += ")";
  return s;
}

}  // namespace

PathRecorder::PathRecorder(const Scene& reference_scene) {
  base_.scene = reference_scene;
  base_.steps = reference_scene.steps();
  dt_ = reference_scene.dt;
  const State s0 = reference_scene.initial_state();
  radius_ = s0.radius;
  base_.reference.resize(static_cast<std::size_t>(s0.x.cols()));
  base_.mine.resize(static_cast<std::size_t>(s0.x.cols()));
  keep(s0, s0);
  last_mine_ = last_reference_ = s0.x;
  recent_.push_back({0, s0.t, s0.x});
}

void PathRecorder::keep(const State& mine, const State& reference) {
  for (std::size_t i = 0; i < base_.mine.size(); ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    base_.mine[i].emplace_back(mine.x.col(k));
    base_.reference[i].emplace_back(reference.x.col(k));
  }
  if (base_.mine.empty() || base_.mine[0].size() <= kMaxSamples) return;
  // Keep the even samples (steps that are multiples of twice the stride).
  for (auto* paths : {&base_.mine, &base_.reference})
    for (auto& p : *paths) {
      std::size_t w = 0;
      for (std::size_t r = 0; r < p.size(); r += 2) p[w++] = p[r];
      p.resize(w);
    }
  stride_ *= 2;
}

void PathRecorder::add(uint64_t n, const State& mine, const State& reference) {
  if (mine.x.cols() != last_mine_.cols() || reference.x.cols() != last_reference_.cols()) return;
  last_step_ = n;
  last_t_ = mine.t;
  last_mine_ = mine.x;
  last_reference_ = reference.x;
  if (n % stride_ == 0) keep(mine, reference);
  recent_.push_back({n, mine.t, mine.x});
  if (recent_.size() > kRecentSteps + 1) recent_.pop_front();
}

PathComparison PathRecorder::failed(std::size_t particle, const BackendInstance* table) const {
  PathComparison c = base_;
  // The failing step ends every path, whatever the stride.
  if (last_step_ % stride_ != 0)
    for (std::size_t i = 0; i < c.mine.size(); ++i) {
      const auto k = static_cast<Eigen::Index>(i);
      c.mine[i].emplace_back(last_mine_.col(k));
      c.reference[i].emplace_back(last_reference_.col(k));
    }
  c.step = c.drawn_to = last_step_;
  c.t = last_t_;
  c.particle = std::min(particle, c.mine.empty() ? 0 : c.mine.size() - 1);
  if (!c.mine.empty()) {
    c.mine_at = last_mine_.col(static_cast<Eigen::Index>(c.particle));
    c.reference_at = last_reference_.col(static_cast<Eigen::Index>(c.particle));
  }
  if (table == nullptr || !table->has_distance()) return c;
  // Each step's drift moves a ball along the straight segment from its last position to its
  // new one: sphere-trace the centre along it against the obstacles at the time it passes
  // (phi is 1-Lipschitz, so a step of phi never jumps over a solid). A centre that comes
  // within a millionth of the radius of a solid has gone into it: a ball that stays outside
  // keeps its centre a radius away.
  for (std::size_t s = 1; s < recent_.size(); ++s) {
    const Recent &a = recent_[s - 1], &b = recent_[s];
    for (Eigen::Index i = 0; i < b.x.cols(); ++i) {
      const Eigen::Vector2d x0 = a.x.col(i), x1 = b.x.col(i);
      const double len = (x1 - x0).norm();
      if (!std::isfinite(len)) continue;
      const double eps = 1e-6 * std::max(radius_[i], 1e-9);
      const double t0 = b.t - dt_;
      double along = 0.0;
      for (int it = 0; it < kTraceIterations; ++it) {
        const double f = len > 0 ? std::min(along / len, 1.0) : 1.0;
        const Eigen::Vector2d p = x0 + f * (x1 - x0);
        const double t = t0 + f * dt_;
        int64_t k = -1;
        const double d = table->distance(p.x(), p.y(), t, &k);
        if (!std::isfinite(d)) break;
        if (d <= eps) {
          c.crossing = PathComparison::Crossing{b.step, t, static_cast<std::size_t>(i), p,
                                                base_.scene.obstacle_id(k)};
          return c;
        }
        if (along >= len) break;
        along += d;
      }
    }
  }
  return c;
}

std::string comparison_caption(const PathComparison& c) {
  std::string s = "The table at t = " + num(c.t, 6) + " s. Ring: step " + std::to_string(c.step) +
                  " of " + std::to_string(c.steps) + ", " + c.what + ": your particle " +
                  std::to_string(c.particle) + " is at " + point(c.mine_at) +
                  ", the reference's at " + point(c.reference_at) + ", " +
                  num((c.mine_at - c.reference_at).norm(), 3) + " apart.";
  if (c.drawn_to > c.step) s += " The paths are drawn to step " + std::to_string(c.drawn_to) + ".";
  if (c.crossing) {
    const auto& x = *c.crossing;
    s += " Cross: where your particle " + std::to_string(x.particle) + "'s centre went into " +
         (x.obstacle.empty() ? std::string("an obstacle") : "obstacle " + x.obstacle) + ", at " +
         point(x.at) + ", t = " + num(x.t, 6) + " s, during step " + std::to_string(x.step) + ".";
  }
  return s;
}

}  // namespace pinsim::grading
