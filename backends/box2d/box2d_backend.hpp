// Box2dBackend: the reference collision backend. The scene's obstacles become fixtures of
// a b2World (Box2D 2.4.1, float), particles become circle bodies; each step the framework's
// kicked velocities are set, the world steps with zero gravity and the positions and
// velocities are read back. Box2D resolves the contacts; forces stay in the framework.
#pragma once

#include <box2d/box2d.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <pinsim/plugin.hpp>
#include <pinsim/scene_field/obstacle_field.hpp>
#include <string>
#include <vector>

namespace pinsim::box2d {

/// Counters since construction.
struct Box2dStats {
  uint64_t steps = 0;            ///< world steps
  uint64_t contact_updates = 0;  ///< PreSolve calls (touching contacts)
  uint64_t events = 0;           ///< impacts reported
  uint64_t free_flights = 0;     ///< particle steps without any contact (exact drift)
};

class Box2dBackend {
 public:
  static PluginInfo info();
  explicit Box2dBackend(const CreateContext& ctx);
  ~Box2dBackend();
  Box2dBackend(const Box2dBackend&) = delete;
  Box2dBackend& operator=(const Box2dBackend&) = delete;

  /// Sets the bodies' velocities to s.v, steps the world over dt and reads back.
  void advance(MutableState& s, double dt, EventSink& ev);
  /// Input `name` pressed or released at time t, between steps: the listening obstacles'
  /// timelines get the event; the kinematic bodies follow from the next step on, from the
  /// pose they have (nothing is rebuilt). Throws Error naming an unknown input.
  void input(const std::string& name, bool pressed, double t) { field_.input(name, pressed, t); }
  /// Signed distance to the nearest obstacle at time t (the exact SDF, for tools).
  double distance(const Vec2& p, double t, int64_t* obstacle) const;
  /// The obstacles' outlines and bounds from the shared obstacle description, as the sdf
  /// backend reports them (sdf::outline_set): the shapes the fixtures are built from.
  OutlineSet outline(const StateView& s, double tolerance) const {
    return sdf::outline_set(field_, s, tolerance);
  }

  /// Box2D length units per scene unit.
  double length_scale() const { return scale_; }
  const Box2dStats& stats() const { return stats_; }
  /// Number of fixtures built for obstacle k.
  std::size_t fixtures(std::size_t k) const { return obstacle_fixtures_[k]; }

  /// The shortest obstacle edge Box2D was given (scene units) and its obstacle's id.
  struct Thinnest {
    double length = HUGE_VAL;
    std::string obstacle;
  };

  /// What a fixture stands for (its user data indexes tags_).
  struct Tag {
    int64_t particle = -1;  ///< particle index, or -1
    int64_t obstacle = -1;  ///< obstacle index, or -1
  };
  /// One impact seen by the contact listener this step.
  struct Pending {
    const b2Contact* contact = nullptr;
    pinsim_event e{};
    b2Body* other = nullptr;  ///< obstacle body or other particle's body
    bool open = true;         ///< vn_after not filled yet
  };

 private:
  friend class Listener;
  /// The scene's obstacles as bodies and fixtures (constructor stage).
  void add_obstacles(const CreateContext& ctx, float threshold);
  /// The particles as circle bodies (constructor stage).
  void add_particles(const CreateContext& ctx, bool friction, float threshold);
  /// Throws before a step Box2D cannot take as asked (see the definition).
  void check_particles(const MutableState& st, double dt) const;
  void on_presolve(b2Contact* c);
  void close_events_of(int64_t particle);
  double vn_now(const Pending& p) const;

  sdf::ObstacleField field_;  ///< validation, materials, scripted motion, distance()
  std::unique_ptr<b2World> world_;
  std::unique_ptr<b2ContactListener> listener_;
  std::vector<Tag> tags_;
  std::vector<b2Body*> particle_body_;
  std::vector<b2Body*> obstacle_body_;
  std::vector<std::size_t> obstacle_fixtures_;
  std::vector<Vec2> last_x_;  ///< positions written back last step (to detect changes)
  std::vector<uint8_t> touched_;
  std::vector<double> track_t_;  ///< per particle: time and Box2D position of the last
  std::vector<b2Vec2> track_x_;  ///< known point of its path this step (for times of impact)
  std::vector<Pending> pending_;
  Thinnest thinnest_;
  double scale_ = 1.0;
  int velocity_iterations_ = 8;
  int position_iterations_ = 3;
  double rest_speed_ = 0.0;
  bool particle_contacts_ = false;
  double particle_e_ = 1.0;
  double t0_ = 0.0, dt_ = 0.0;
  Box2dStats stats_;
};

}  // namespace pinsim::box2d
