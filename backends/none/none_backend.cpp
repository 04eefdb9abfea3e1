// The `none` backend: pure drift x += dt v, no obstacles, no contacts.
#include <pinsim/plugin.hpp>

namespace pinsim::backends {

class NoneBackend {
 public:
  static PluginInfo info() {
    PluginInfo i;
    i.name = "none";
    i.doc = "Pure drift x(t+dt) = x(t) + dt v for scenes without obstacles; no collision work.";
    i.capabilities = PINSIM_CAP_DIFFERENTIABLE;  // the drift is x += dt v, nothing else
    return i;
  }

  explicit NoneBackend(const CreateContext& ctx) {
    const auto& obstacles = ctx.scene.value("obstacles", nlohmann::json::array());
    if (!obstacles.empty())
      throw Error(ctx.context + ": backend 'none' has no collisions, but the scene lists " +
                  std::to_string(obstacles.size()) + " obstacle(s); use backend 'sdf' or 'box2d'");
  }

  /// x += dt v for every particle with finite mass; pinned particles do not move.
  void advance(MutableState& s, double dt, EventSink&) {
    for (Eigen::Index i = 0; i < s.x.cols(); ++i)
      if (s.inv_mass[i] > 0.0) s.x.col(i) += dt * s.v.col(i);
  }

  /// No obstacles: every point is infinitely far from one.
  double distance(const Vec2&, double, int64_t* obstacle) const {
    if (obstacle) *obstacle = -1;
    return HUGE_VAL;
  }

  /// No obstacles: nothing to outline, empty bounds.
  OutlineSet outline(const StateView&, double) const { return {}; }
};

}  // namespace pinsim::backends

PINSIM_PLUGIN(pinsim::backends::NoneBackend)
