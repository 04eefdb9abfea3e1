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
