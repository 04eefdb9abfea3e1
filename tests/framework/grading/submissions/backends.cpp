// Student collision backends for the grader tests, one per -DSUBMISSION value:
//   0: correct (the reference sdf backend under the student's plugin name)
//   1: tunnels (pure drift: never looks at the obstacles)
//   2: applies an impulse while separating (reflects v whenever the ball is within reach of
//      an obstacle, approaching or not)
// 3-5: forgeries of backend_approaching_only: the reference backend, plus, in the first step,
//      an extra push away from the obstacle to a ball that is already separating from it;
//   3: reports nothing about the push
//   4: reports it with a false vn_before < 0 (approaching)
//   5: reports it with vn_before = NaN
// 6-8: adversaries of the motion gate, each reporting the reference's contacts:
//   6: does nothing at all (the balls never move)
//   7: moves them as the reference does, then puts them back where the step started
//   8: moves them as the reference does, then zeroes their velocity (stops them)
//   9: naive discrete detection (the assignment's starter): drift over the step, one check
//      of the SDF at its end, a restitution impulse if the ball overlaps and approaches
#include <cmath>

#include "sdf_backend.hpp"

namespace {

class StudentBackend : public pinsim::sdf::SdfBackend {
 public:
  using SdfBackend::SdfBackend;
  static pinsim::PluginInfo info() {
    auto i = SdfBackend::info();
    i.name = "student_sdf";
    return i;
  }
  /// The obstacles' outward unit normal at p: central differences of the distance (h = 1e-6).
  pinsim::Vec2 normal(const pinsim::Vec2& p, double t) const {
    const double h = 1e-6;
    const pinsim::Vec2 dx(h, 0), dy(0, h);
    const pinsim::Vec2 g((distance(p + dx, t, nullptr) - distance(p - dx, t, nullptr)) / (2 * h),
                         (distance(p + dy, t, nullptr) - distance(p - dy, t, nullptr)) / (2 * h));
    return g.normalized();
  }
#if SUBMISSION == 1
  void advance(pinsim::MutableState& s, double dt, pinsim::EventSink&) {
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) s.x.col(i) += dt * s.v.col(i);
  }
#elif SUBMISSION == 2
  void advance(pinsim::MutableState& s, double dt, pinsim::EventSink& ev) {
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
      const pinsim::Vec2 p = s.x.col(i);
      int64_t obstacle = -1;
      const double d = distance(p, s.t, &obstacle) - s.radius[i];
      if (d < s.v.col(i).norm() * dt + 1e-3) {
        const pinsim::Vec2 n = normal(p, s.t);
        const double vn = s.v.col(i).dot(n);
        s.v.col(i) -= 2.0 * vn * n;  // the bug: no check that vn < 0
        pinsim_event e{s.t, i, obstacle, -1, {p.x(), p.y()}, {n.x(), n.y()}, vn, -vn};
        ev.emit(e);
      }
      s.x.col(i) += dt * s.v.col(i);
    }
  }
#elif SUBMISSION == 6
  void advance(pinsim::MutableState&, double, pinsim::EventSink&) {}
#elif SUBMISSION == 7 || SUBMISSION == 8
  void advance(pinsim::MutableState& s, double dt, pinsim::EventSink& ev) {
    const Eigen::Matrix2Xd x0 = s.x;
    SdfBackend::advance(s, dt, ev);
#if SUBMISSION == 7
    s.x = x0;
#else
    s.v.setZero();
#endif
  }
#elif SUBMISSION == 9
  void advance(pinsim::MutableState& s, double dt, pinsim::EventSink& ev) {
    const double t1 = s.t + dt;
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
      s.x.col(i) += dt * s.v.col(i);
      const pinsim::Vec2 p = s.x.col(i);
      int64_t obstacle = -1;
      if (distance(p, t1, &obstacle) >= s.radius[i] || obstacle < 0) continue;
      const pinsim::Vec2 n = normal(p, t1);
      const double vn = s.v.col(i).dot(n);
      if (vn >= 0.0) continue;
      const auto& o = field().obstacle(static_cast<std::size_t>(obstacle));
      s.v.col(i) -= (1.0 + o.material.restitution) * vn * n;
      pinsim_event e{t1, i, obstacle, -1, {p.x(), p.y()}, {n.x(), n.y()}, vn, s.v.col(i).dot(n)};
      ev.emit(e);
    }
  }
#elif SUBMISSION >= 3
  void advance(pinsim::MutableState& s, double dt, pinsim::EventSink& ev) {
    SdfBackend::advance(s, dt, ev);
    if (s.t != 0.0) return;
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
      const pinsim::Vec2 p = s.x.col(i);
      int64_t obstacle = -1;
      const double d = distance(p, s.t, &obstacle) - s.radius[i];
      if (obstacle < 0 || d > 1e-2) continue;
      const pinsim::Vec2 n = normal(p, s.t);
      const double vn = s.v.col(i).dot(n);
      if (vn <= 0.01) continue;  // only a ball already leaving
      s.v.col(i) += 0.5 * vn * n;
#if SUBMISSION == 4
      pinsim_event e{s.t, i, obstacle, -1, {p.x(), p.y()}, {n.x(), n.y()}, -vn, 1.5 * vn};
      ev.emit(e);
#elif SUBMISSION == 5
      pinsim_event e{s.t, i, obstacle, -1, {p.x(), p.y()}, {n.x(), n.y()}, std::nan(""), 1.5 * vn};
      ev.emit(e);
#endif
    }
  }
#endif
};

}  // namespace

PINSIM_PLUGIN(StudentBackend)
