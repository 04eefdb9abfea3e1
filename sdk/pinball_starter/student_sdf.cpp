// student_sdf: the Pinball assignment's starter backend (docs/pinball_assignment.md).
//
// The host integrates the forces with symplectic Euler (v += dt f / m); advance() is the
// rest of the ball's time step: it moves each ball over the whole step, x += dt v, then
// looks at the scene's signed distance field phi once, at the end of the step, and if the
// ball overlaps an obstacle (phi(x) < r) and approaches it (vn = v.n < 0) applies the
// restitution impulse
//     v' = v - (1 + e) vn n + kick n,        n = grad phi(x) (the outward normal).
// This is deliberately naive (discrete detection): a fast ball passes through a thin wall
// between two checks, only one collision per step is seen, a resting ball sinks into the
// floor and jitters (nothing puts it back on the surface), and a moving flipper's velocity
// is ignored. Making it robust is the assignment.
//
// The obstacles come from pinsim::sdf::FieldBackend (pinsim/scene_field.hpp): field_ answers
// phi, grad phi, the obstacle's material and surface velocity at any point and time, and
// the base class gives the backend distance(), input() and outline(), so pinsim play,
// render, replay and share show the table.
#include <pinsim/plugin.hpp>
#include <pinsim/scene_field.hpp>

namespace {

using pinsim::Vec2;

class StudentSdf : public pinsim::sdf::FieldBackend {
 public:
  static pinsim::PluginInfo info() {
    pinsim::PluginInfo i;
    i.name = "student_sdf";  // the collision rubric loads the plugin by this name
    i.version = "0.1.0";
    i.doc =
        "Pinball assignment starter: drift x += dt v, then one discrete check of the scene's "
        "SDF at the end of the step and a restitution impulse when the ball approaches "
        "(tunnels through thin walls; replace with sphere tracing).";
    return i;
  }

  explicit StudentSdf(const pinsim::CreateContext& ctx) : FieldBackend(ctx) {}

  void advance(pinsim::MutableState& s, double dt, pinsim::EventSink& events) {
    const double t1 = s.t + dt;  // the obstacles' time at the end of the step
    for (std::size_t i = 0; i < s.n; ++i) {
      if (s.inv_mass[static_cast<Eigen::Index>(i)] == 0.0) continue;  // pinned
      auto x = s.x.col(static_cast<Eigen::Index>(i));
      auto v = s.v.col(static_cast<Eigen::Index>(i));
      const double r = s.radius[static_cast<Eigen::Index>(i)];

      x += dt * v;  // drift over the whole step

      // One discrete check at the end of the step.
      const pinsim::sdf::Nearest hit = field_.nearest_with_gradient(x, t1);
      if (hit.k < 0 || hit.d >= r) continue;  // no overlap
      const Vec2 n = hit.g;
      const double vn = v.dot(n);  // TODO: relative to the obstacle's velocity (flippers)
      if (vn >= 0.0) continue;     // separating: no impulse
      const pinsim::sdf::Material& m = field_.obstacle(static_cast<std::size_t>(hit.k)).material;
      v -= (1.0 + m.restitution) * vn * n;
      v += m.kick * n;

      const Vec2 point = Vec2(x) - hit.d * n;  // the closest surface point
      pinsim_event e{};
      e.t = t1;
      e.particle = static_cast<int64_t>(i);
      e.obstacle = hit.k;
      e.other = -1;
      e.point[0] = point.x();
      e.point[1] = point.y();
      e.normal[0] = n.x();
      e.normal[1] = n.y();
      e.vn_before = vn;
      e.vn_after = v.dot(n);
      events.emit(e);
    }
  }
};

}  // namespace

PINSIM_PLUGIN(StudentSdf)
