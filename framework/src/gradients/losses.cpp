#include "gradients/losses.hpp"

#include <charconv>
#include <cmath>
#include <utility>

#include "core/format.hpp"
#include "core/input_error.hpp"

namespace pinsim::grad {
namespace {

[[noreturn]] void bad(const std::string& spec, const std::string& what) {
  throw InputError("--loss " + spec + ": " + what +
                   " (expected final:I:x|y|vx|vy, target:I:X,Y[@T] or misfit:RUN_FOLDER)");
}

double parse_number(const std::string& spec, const std::string& text, const char* what) {
  double v = 0.0;
  const char* b = text.data();
  const char* e = b + text.size();
  const auto r = std::from_chars(b, e, v);
  if (text.empty() || r.ec != std::errc{} || r.ptr != e || !std::isfinite(v))
    bad(spec, std::string(what) + " '" + text + "' is not a finite number");
  return v;
}

std::size_t parse_particle(const std::string& spec, const std::string& text,
                           const LossContext& ctx) {
  std::size_t i = 0;
  const char* b = text.data();
  const char* e = b + text.size();
  const auto r = std::from_chars(b, e, i);
  if (text.empty() || r.ec != std::errc{} || r.ptr != e)
    bad(spec, "particle '" + text + "' is not an index");
  if (i >= ctx.particles)
    bad(spec, "particle " + text + " does not exist (the scene has " +
                  std::to_string(ctx.particles) + ")");
  return i;
}

/// The final coordinate c (0 x, 1 y, 2 vx, 3 vy) of particle i.
class FinalCoordinate : public Loss {
 public:
  FinalCoordinate(std::size_t i, int c, uint64_t steps, std::string text)
      : i_(static_cast<Eigen::Index>(i)), c_(c), steps_(steps), text_(std::move(text)) {}
  bool has_term(uint64_t n) const override { return n == steps_; }
  double term(uint64_t n, const State& s, Eigen::Matrix2Xd& gx,
              Eigen::Matrix2Xd& gv) const override {
    if (n != steps_) return 0.0;
    if (c_ < 2) {
      gx(c_, i_) += 1.0;
      return s.x(c_, i_);
    }
    gv(c_ - 2, i_) += 1.0;
    return s.v(c_ - 2, i_);
  }
  std::string describe() const override { return text_; }

 private:
  Eigen::Index i_;
  int c_;
  uint64_t steps_;
  std::string text_;
};

/// |x_i - target|^2 after step n.
class TargetDistance : public Loss {
 public:
  TargetDistance(std::size_t i, Eigen::Vector2d target, uint64_t n, std::string text)
      : i_(static_cast<Eigen::Index>(i)), target_(target), n_(n), text_(std::move(text)) {}
  bool has_term(uint64_t n) const override { return n == n_; }
  double term(uint64_t n, const State& s, Eigen::Matrix2Xd& gx, Eigen::Matrix2Xd&) const override {
    if (n != n_) return 0.0;
    const Eigen::Vector2d d = s.x.col(i_) - target_;
    gx.col(i_) += 2.0 * d;
    return d.squaredNorm();
  }
  std::string describe() const override { return text_; }

 private:
  Eigen::Index i_;
  Eigen::Vector2d target_;
  uint64_t n_;
  std::string text_;
};

class Misfit : public Loss {
 public:
  explicit Misfit(RecordedFrames f) : f_(std::move(f)) {
    for (std::size_t k = 0; k < f_.steps.size(); ++k) index_.emplace_back(f_.steps[k], k);
  }
  bool has_term(uint64_t n) const override { return find(n) >= 0; }
  double term(uint64_t n, const State& s, Eigen::Matrix2Xd& gx, Eigen::Matrix2Xd&) const override {
    const int64_t k = find(n);
    if (k < 0) return 0.0;
    const auto& x = f_.x[static_cast<std::size_t>(k)];
    const auto& present = f_.present[static_cast<std::size_t>(k)];
    double sum = 0.0;
    for (Eigen::Index i = 0; i < x.cols(); ++i) {
      if (!present[static_cast<std::size_t>(i)]) continue;
      const Eigen::Vector2d d = s.x.col(i) - x.col(i);
      gx.col(i) += 2.0 * d;
      sum += d.squaredNorm();
    }
    return sum;
  }
  std::string describe() const override {
    return "misfit to " + f_.source + " (" + std::to_string(f_.steps.size()) +
           " frames: sum of squared position differences)";
  }

 private:
  int64_t find(uint64_t n) const {
    std::size_t lo = 0, hi = index_.size();
    while (lo < hi) {
      const std::size_t mid = (lo + hi) / 2;
      if (index_[mid].first < n)
        lo = mid + 1;
      else
        hi = mid;
    }
    return lo < index_.size() && index_[lo].first == n ? static_cast<int64_t>(index_[lo].second)
                                                       : -1;
  }
  RecordedFrames f_;
  std::vector<std::pair<uint64_t, std::size_t>> index_;
};

}  // namespace

int64_t step_of_time(double t, double dt) {
  if (!(dt > 0.0) || !std::isfinite(t) || t < 0.0) return -1;
  const double k = std::round(t / dt);
  if (!(std::abs(k * dt - t) <= 1e-9 * std::max(t, dt))) return -1;
  return static_cast<int64_t>(k);
}

std::unique_ptr<Loss> parse_loss(const std::string& spec, const LossContext& ctx) {
  const auto colon = spec.find(':');
  if (colon == std::string::npos) bad(spec, "no kind");
  const std::string kind = spec.substr(0, colon), rest = spec.substr(colon + 1);
  if (kind == "final") {
    const auto c2 = rest.find(':');
    if (c2 == std::string::npos) bad(spec, "expected final:I:COORDINATE");
    const std::size_t i = parse_particle(spec, rest.substr(0, c2), ctx);
    const std::string c = rest.substr(c2 + 1);
    const int ci = c == "x" ? 0 : c == "y" ? 1 : c == "vx" ? 2 : c == "vy" ? 3 : -1;
    if (ci < 0) bad(spec, "coordinate '" + c + "' is not x, y, vx or vy");
    return std::make_unique<FinalCoordinate>(i, ci, ctx.steps,
                                             "final " + c + " of particle " + std::to_string(i));
  }
  if (kind == "target") {
    const auto c2 = rest.find(':');
    if (c2 == std::string::npos) bad(spec, "expected target:I:X,Y[@T]");
    const std::size_t i = parse_particle(spec, rest.substr(0, c2), ctx);
    std::string point = rest.substr(c2 + 1);
    uint64_t n = ctx.steps;
    if (const auto at = point.find('@'); at != std::string::npos) {
      const double t = parse_number(spec, point.substr(at + 1), "time");
      const int64_t k = step_of_time(t, ctx.dt);
      if (k < 0 || static_cast<uint64_t>(k) > ctx.steps)
        bad(spec, "time " + num(t) + " s is not a step time of the run (dt = " + num(ctx.dt) +
                      " s, " + std::to_string(ctx.steps) + " steps)");
      n = static_cast<uint64_t>(k);
      point = point.substr(0, at);
    }
    const auto comma = point.find(',');
    if (comma == std::string::npos) bad(spec, "expected the target as X,Y");
    const Eigen::Vector2d target(parse_number(spec, point.substr(0, comma), "X"),
                                 parse_number(spec, point.substr(comma + 1), "Y"));
    return std::make_unique<TargetDistance>(
        i, target, n,
        "squared distance of particle " + std::to_string(i) + " to (" + num(target.x()) + ", " +
            num(target.y()) + ") at t = " + num(static_cast<double>(n) * ctx.dt) + " s");
  }
  if (kind == "misfit") bad(spec, "a misfit needs its run folder read first");
  bad(spec, "unknown kind '" + kind + "'");
}

std::unique_ptr<Loss> make_misfit(RecordedFrames frames, const LossContext& ctx) {
  for (std::size_t k = 0; k < frames.steps.size(); ++k) {
    if (frames.steps[k] > ctx.steps)
      throw InputError(frames.source + ": frame at step " + std::to_string(frames.steps[k]) +
                       " is past the run's " + std::to_string(ctx.steps) + " steps");
    if (static_cast<std::size_t>(frames.x[k].cols()) > ctx.particles)
      throw InputError(frames.source + ": has " + std::to_string(frames.x[k].cols()) +
                       " particles, the scene " + std::to_string(ctx.particles));
    if (k > 0 && !(frames.steps[k] > frames.steps[k - 1]))
      throw InputError(frames.source + ": frames are not in increasing time order");
  }
  return std::make_unique<Misfit>(std::move(frames));
}

}  // namespace pinsim::grad
