// A reference solution of the Pinball assignment (docs/pinball_assignment.md): the starter
// kit's student_sdf made robust. Kept in tests/ (not in the kit); the collision rubric must
// give it full marks.
//
// Each ball moves along x(s) = x + v s over the step by sphere tracing its centre against
// the clearance c = phi - r: along the path c changes at most at L = |v| + U (U bounds how
// fast the moving obstacles' fields change), so no contact can happen before
// s = (c - depthMin) / L, which is the step taken. Within depthMin (1 + tolerance) of the
// surface, the nearest obstacle gives n = grad phi, the contact point p = x - phi n and its
// surface velocity u; the normal velocity relative to the surface is vn = (v - u).n, and
//   vn < 0 (approaching):  v' = v - (1 + e) vn n + kick n   (one event, at most kCap a step)
//   vn >= 0 (separating):  no impulse; move on by max(c, depthMin) / L (sliding along a
//                          surface so takes steps of depthMin, at most kMaxIterations).
// A ball closer than depthMin is put back to depthMin along n. A ball that reaches the cap
// stays where it is for the rest of the step.
#include <algorithm>
#include <cmath>
#include <pinsim/plugin.hpp>
#include <pinsim/scene_field.hpp>
#include <vector>

namespace {

using pinsim::Vec2;

constexpr double kDepthMin = 1e-5;      ///< contact offset, scene length
constexpr double kTolerance = 0.1;      ///< the march stops within this fraction above it
constexpr int kCap = 16;                ///< impulses per ball per step
constexpr int kMaxIterations = 100000;  ///< march steps per ball per step

class StudentSdf : public pinsim::sdf::FieldBackend {
 public:
  static pinsim::PluginInfo info() {
    pinsim::PluginInfo i;
    i.name = "student_sdf";
    i.version = "1.0.0";
    i.doc =
        "Pinball assignment reference solution: sphere tracing against phi - r with depthMin, "
        "every collision of a step (capped), impulses only while approaching, relative to the "
        "obstacle's surface velocity.";
    return i;
  }

  explicit StudentSdf(const pinsim::CreateContext& ctx) : FieldBackend(ctx) {}

  void advance(pinsim::MutableState& s, double dt, pinsim::EventSink& events) {
    // U: the fastest moving obstacle's speed bound over the step.
    double u_max = 0.0;
    hints_.resize(field_.size(), 0);
    for (uint32_t k : field_.moving())
      u_max = std::max(u_max, field_.speed_bound(k, s.t, s.t + dt, hints_[k]));
    for (std::size_t i = 0; i < s.n; ++i) {
      const auto j = static_cast<Eigen::Index>(i);
      if (s.inv_mass[j] == 0.0) continue;
      Vec2 x = s.x.col(j), v = s.v.col(j);
      march(static_cast<int64_t>(i), x, v, s.radius[j], s.t, dt, u_max, events);
      s.x.col(j) = x;
      s.v.col(j) = v;
    }
  }

 private:
  void march(int64_t i, Vec2& x, Vec2& v, double r, double t, double dur, double u_max,
             pinsim::EventSink& events) const {
    const double band = kDepthMin * (1.0 + kTolerance);
    int impulses = 0;
    for (int it = 0; it < kMaxIterations && dur > 0.0; ++it) {
      const pinsim::sdf::Nearest h = field_.nearest_with_gradient(x, t);
      const double c = h.d - r;
      const double L = v.norm() + u_max;
      double step;
      if (h.k < 0 || c > band) {
        step = L > 0.0 ? (c - kDepthMin) / L : dur;
      } else {
        const auto k = static_cast<std::size_t>(h.k);
        const Vec2 n = h.g;
        const Vec2 u = field_.velocity(k, x - h.d * n, t);
        const double vn = (v - u).dot(n);
        if (c < kDepthMin) x += (kDepthMin - c) * n;  // back to the offset
        if (vn < 0.0) {
          if (impulses == kCap) return;  // the cap: stay for the rest of the step
          ++impulses;
          const pinsim::sdf::Material& m = field_.obstacle(k).material;
          v -= (1.0 + m.restitution) * vn * n;
          v += m.kick * n;
          pinsim_event e{};
          e.t = t;
          e.particle = i;
          e.obstacle = h.k;
          e.other = -1;
          const Vec2 p = x - (r + kDepthMin) * n;
          e.point[0] = p.x();
          e.point[1] = p.y();
          e.normal[0] = n.x();
          e.normal[1] = n.y();
          e.vn_before = vn;
          e.vn_after = (v - u).dot(n);
          events.emit(e);
          continue;
        }
        step = std::max(c, kDepthMin) / L;  // cannot take it deeper than 0 below the offset
      }
      step = std::min(step, dur);
      x += step * v;
      t += step;
      dur -= step;
    }
  }

  mutable std::vector<std::size_t> hints_;
};

}  // namespace

PINSIM_PLUGIN(StudentSdf)
