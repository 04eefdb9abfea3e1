// Timeline: a piecewise-linear scalar driven by press/release events (flipper angle,
// slider position), exact at any time.
#pragma once

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace pinsim::sdf {

class Timeline {
 public:
  /// Starts at `rest`; while pressed moves towards `pressed` at `speed_press` (> 0, per s),
  /// while released back towards `rest` at `speed_release`; stops on reaching the target.
  /// `events` are (time, pressed?) in time order.
  Timeline(double rest, double pressed, double speed_press, double speed_release,
           std::vector<std::pair<double, bool>> events)
      : rest_(rest),
        pressed_(pressed),
        speed_press_(speed_press),
        speed_release_(speed_release),
        lo_(std::min(rest, pressed)),
        hi_(std::max(rest, pressed)),
        events_(std::move(events)) {
    build();
  }

  /// Appends an event at time t (at or after the last one): the same segments as
  /// constructing with the longer event list.
  void add_event(double t, bool press) {
    events_.emplace_back(t, press);
    build();
  }
  /// The events so far, (time, pressed?) in time order.
  const std::vector<std::pair<double, bool>>& events() const { return events_; }

  /// Value at time t.
  double value(double t) const {
    const Seg& s = at(t);
    return s.slope == 0.0 ? s.v : s.v + s.slope * (t - s.t);
  }
  /// Value at time t with its cosine and sine (an angle); the same bits as std::cos and
  /// std::sin of value(t), taken from the segment while the value stands still.
  double value_cos_sin(double t, double& c, double& sn) const {
    const Seg& s = at(t);
    if (s.slope == 0.0) {
      c = s.c;
      sn = s.s;
      return s.v;
    }
    const double v = s.v + s.slope * (t - s.t);
    c = std::cos(v);
    sn = std::sin(v);
    return v;
  }
  /// Rate of change at time t (the segment starting at or before t).
  double rate(double t) const { return at(t).slope; }
  /// Largest |rate| over [t0, t1], starting the search at segment `hint` (updated), for
  /// times that advance.
  double max_rate(double t0, double t1, std::size_t& hint) const {
    if (!(hint < seg_.size() && seg_[hint].t <= t0 &&
          (hint + 1 == seg_.size() || t0 < seg_[hint + 1].t)))
      hint = index(t0);
    double m = 0.0;
    for (std::size_t k = hint; k < seg_.size() && seg_[k].t <= t1; ++k)
      m = std::max(m, std::abs(seg_[k].slope));
    return m;
  }
  /// Least and greatest value it can take (rest and pressed).
  double lo() const { return lo_; }
  double hi() const { return hi_; }
  /// True if the value never changes.
  bool constant() const { return seg_.size() == 1; }

 private:
  struct Seg {
    double t, v, slope;
    double c, s;  ///< cos v, sin v
  };
  /// Segments from the parameters and events_.
  void build() {
    seg_.clear();
    push(0.0, rest_, 0.0);
    double target = rest_;
    for (const auto& [te, press] : events_) {
      const Seg& last = seg_.back();
      const double te_c = std::max(te, last.t);
      // reached the current target before this event?
      if (last.slope != 0.0) {
        const double t_reach = last.t + std::abs(target - last.v) / std::abs(last.slope);
        if (t_reach <= te_c) push(t_reach, target, 0.0);
      }
      const Seg& cur = seg_.back();
      const double v = cur.slope == 0.0 ? cur.v : cur.v + cur.slope * (te_c - cur.t);
      target = press ? pressed_ : rest_;
      const double speed = press ? speed_press_ : speed_release_;
      const double slope = target > v ? speed : (target < v ? -speed : 0.0);
      push(te_c, v, slope);
    }
    const Seg& last = seg_.back();
    if (last.slope != 0.0)
      push(last.t + std::abs(target - last.v) / std::abs(last.slope), target, 0.0);
  }
  void push(double t, double v, double slope) {
    const Seg g{t, v, slope, std::cos(v), std::sin(v)};
    if (!seg_.empty() && seg_.back().t == t)
      seg_.back() = g;
    else
      seg_.push_back(g);
  }
  /// The last segment starting at or before t (0 if none), as upper_bound - 1; a binary
  /// search without data-dependent branches (random query times mispredict them).
  std::size_t index(double t) const {
    const Seg* base = seg_.data();
    std::size_t n = seg_.size();
    while (n > 1) {
      const std::size_t half = n / 2;
      base = !(t < base[half].t) ? base + half : base;
      n -= half;
    }
    return static_cast<std::size_t>(base - seg_.data());
  }
  const Seg& at(double t) const { return seg_[index(t)]; }

  double rest_ = 0.0, pressed_ = 0.0, speed_press_ = 0.0, speed_release_ = 0.0;
  double lo_ = 0.0, hi_ = 0.0;
  std::vector<std::pair<double, bool>> events_;
  std::vector<Seg> seg_;
};

}  // namespace pinsim::sdf
