#include "box2d_backend.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <pinsim/scene_field/json_in.hpp>
#include <sstream>

#include "contact_options.hpp"
#include "preconditions.hpp"
#include "shape_builder.hpp"

namespace pinsim::box2d {

// Box2D calls back into the backend for every touching contact before it is solved.
class Listener : public b2ContactListener {
 public:
  explicit Listener(Box2dBackend* b) : b_(b) {}
  void PreSolve(b2Contact* contact, const b2Manifold*) override { b_->on_presolve(contact); }

 private:
  Box2dBackend* b_;
};

namespace {

b2Vec2 to_b2(const Vec2& p, double s) {
  return b2Vec2(static_cast<float>(p.x() * s), static_cast<float>(p.y() * s));
}
Vec2 from_b2(const b2Vec2& p, double s) {
  return Vec2(static_cast<double>(p.x) / s, static_cast<double>(p.y) / s);
}
std::string num(double x) {
  std::ostringstream o;
  o.precision(4);
  o << x;
  return o.str();
}

// Length scale: Box2D 2.4.1 is tuned for moving objects of 0.1 to 10 units (slop
// 0.005, translation cap 2 units per step). `requested` if > 0, else the smallest particle
// radius becomes 1 unit, shrunk so that the largest moving body (a particle's diameter, a
// flipper's reach) is at most 10 units. Every particle needs a radius > 0.
double choose_length_scale(const CreateContext& ctx, const sdf::ObstacleField& field,
                           double requested) {
  const std::size_t n = ctx.initial.n;
  double r_min = HUGE_VAL, size_max = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r = ctx.initial.radius[static_cast<Eigen::Index>(i)];
    if (!(r > 0.0))
      throw Error(ctx.context + ": particles[" + std::to_string(i) +
                  "].radius: the box2d backend needs a radius > 0 (Box2D circles), got " + num(r));
    r_min = std::min(r_min, r);
    size_max = std::max(size_max, 2.0 * r);
  }
  for (uint32_t k : field.moving()) size_max = std::max(size_max, field.obstacle(k).reach);
  double scale = requested;
  if (scale == 0.0) {
    scale = n > 0 ? 1.0 / r_min : 1.0;
    if (size_max > 0.0) scale = std::min(scale, 10.0 / size_max);
  }
  // (Box2D's floats, and the conversions back, need a scale that neither overflows nor
  // underflows them)
  if (!(scale >= 1.0 / kMaxFloatValue && scale <= kMaxFloatValue))
    throw Error(ctx.context + ": length scale " + num(scale) +
                (requested == 0.0 ? " (1 / the smallest particle radius " + num(r_min) + ")"
                                  : std::string(" (params.length_scale)")) +
                " is outside the range the box2d backend can use, [" + num(1.0 / kMaxFloatValue) +
                ", " + num(kMaxFloatValue) + "]");
  return scale;
}

// Half-plane edges: centred on the particles' mean initial position (the origin without
// particles), long enough to cover the scene many times over.
BuildOptions build_options(const CreateContext& ctx, double s) {
  const std::size_t n = ctx.initial.n;
  Vec2 centre(0.0, 0.0);
  for (std::size_t i = 0; i < n; ++i) centre += ctx.initial.x.col(static_cast<Eigen::Index>(i));
  if (n > 0) centre /= static_cast<double>(n);
  BuildOptions bo;
  bo.curve_segments = static_cast<int>(ctx.params.integer("curve_segments"));
  bo.centre = centre;
  bo.half_plane_extent = 1000.0 / s;  // 1000 Box2D units each way
  return bo;
}

// True if any obstacle has friction (then particles may spin).
bool any_friction(const sdf::ObstacleField& field) {
  bool friction = false;
  for (std::size_t k = 0; k < field.size(); ++k)
    friction = friction || field.obstacle(k).material.friction > 0.0;
  return friction;
}

// An obstacle's body: static, or kinematic in its pose at t = 0 for flippers (angle about
// the pivot) and sliders (offset).
b2BodyDef obstacle_body_def(const sdf::Obstacle& o, double s) {
  b2BodyDef bd;
  if (o.motion == sdf::MotionType::kFlipper) {
    bd.type = b2_kinematicBody;
    bd.position = to_b2(o.pivot, s);
    bd.angle = static_cast<float>(o.timeline->value(0.0));
  } else if (o.motion == sdf::MotionType::kSlider) {
    bd.type = b2_kinematicBody;
    bd.position = to_b2(o.timeline->value(0.0) * o.offset, s);
  }
  return bd;
}

/// A piece of obstacle k's shape on its way into Box2D: its body, fixture settings, the
/// length scale and, for errors, where it comes from.
struct PieceTarget {
  b2Body* body;
  b2FixtureDef fd;  ///< material, threshold and tag; the shape is set per piece
  double s;         ///< length scale
  const std::string& context;
  const std::string& path;           ///< obstacles[k]
  const std::string& id;             ///< the obstacle's id
  Box2dBackend::Thinnest& thinnest;  ///< the shortest edge so far (updated)
};

// Throws "unsupported by box2d" naming the piece unless `problem` is empty.
void require(const PieceTarget& t, const char* what, const std::string& problem) {
  if (problem.empty()) return;
  throw Error(t.context + ": " + t.path + ".shape: unsupported by box2d (obstacle '" + t.id +
              "'): " + what + ": " + problem + " at length scale " + num(t.s));
}

// Throws unless every point (scene units, the obstacle's frame) is within kMaxUnits at the
// length scale.
void check_coordinates(const PieceTarget& t, const std::vector<Vec2>& v, double radius,
                       const char* what) {
  for (const Vec2& p : v) require(t, what, coordinate_problem(p.x() * t.s, p.y() * t.s));
  require(t, what, coordinate_problem(radius * t.s, 0.0));
}

// Throws if an edge of v (with the closing edge if `closed`) is not longer than Box2D's
// weld distance at the length scale; `what` names the piece. Records the shortest edge.
void check_edges(const PieceTarget& t, const std::vector<Vec2>& v, bool closed, const char* what) {
  const double weld = 0.5 * b2_linearSlop;
  for (std::size_t q = 0; q + (closed ? 0 : 1) < v.size(); ++q) {
    const double len = (v[(q + 1) % v.size()] - v[q]).norm();
    if (len < t.thinnest.length) t.thinnest = {len, t.id};
    if (len * t.s <= 2.0 * weld)
      throw Error(t.context + ": " + t.path + ".shape: unsupported by box2d (obstacle '" + t.id +
                  "'): " + what + " has an edge shorter than Box2D's weld distance " +
                  num(2.0 * weld / t.s) + " at length scale " + num(t.s));
  }
}

// Attaches a fixture of `shape` to the target's body.
void attach(PieceTarget& t, const b2Shape& shape) {
  t.fd.shape = &shape;
  t.body->CreateFixture(&t.fd);
}

// A circle piece.
void add_circle(PieceTarget& t, const Piece& pc) {
  check_coordinates(t, pc.v, pc.radius, "a circle");
  b2CircleShape c;
  c.m_p = to_b2(pc.v[0], t.s);
  c.m_radius = static_cast<float>(pc.radius * t.s);
  attach(t, c);
}

// A convex polygon piece (at most b2_maxPolygonVertices points).
void add_polygon(PieceTarget& t, const Piece& pc) {
  check_coordinates(t, pc.v, pc.radius, "a polygon piece");
  require(t, "a polygon piece",
          pc.v.size() <= b2_maxPolygonVertices ? "" : "more than b2_maxPolygonVertices vertices");
  check_edges(t, pc.v, true, "a polygon piece");
  b2Vec2 v[b2_maxPolygonVertices];
  for (std::size_t q = 0; q < pc.v.size(); ++q) v[q] = to_b2(pc.v[q], t.s);
  require(t, "a polygon piece", polygon_problem(v, static_cast<int>(pc.v.size())));
  b2PolygonShape poly;
  poly.Set(v, static_cast<int32>(pc.v.size()));
  // Skin: Box2D inflates polygons by b2_polygonRadius = 0.01 units so that polygon
  // cores never touch. Only circles move here and obstacles never collide with each
  // other, so the radius is set to the shape's own rounding (0 for plain polygons):
  // the surface sits exactly where the SDF has it.
  poly.m_radius = static_cast<float>(pc.radius * t.s);
  attach(t, poly);
}

// A segment piece (a capsule if it has a radius); one-sided ones get ghost vertices that
// continue it straight on both ends.
void add_edge(PieceTarget& t, const Piece& pc) {
  check_coordinates(t, pc.v, pc.radius, "a segment");
  check_edges(t, pc.v, false, "a segment");
  b2EdgeShape e;
  const b2Vec2 a = to_b2(pc.v[0], t.s), b = to_b2(pc.v[1], t.s);
  if (pc.one_sided) {
    const b2Vec2 d = b - a;
    e.SetOneSided(a - d, a, b, b + d);
  } else {
    e.SetTwoSided(a, b);
  }
  e.m_radius = static_cast<float>(pc.radius * t.s);  // capsule radius (skin: see add_polygon)
  attach(t, e);
}

// A container wall: a closed chain, or an open one with the piece's ghost vertices.
void add_chain(PieceTarget& t, const Piece& pc) {
  const bool loop = pc.kind == Piece::Kind::kChainLoop;
  check_coordinates(t, pc.v, 0.0, "a container wall");
  if (!loop) check_coordinates(t, {pc.ghost0, pc.ghost1}, 0.0, "a container wall");
  check_edges(t, pc.v, loop, "a container wall");
  std::vector<b2Vec2> v;
  for (const Vec2& q : pc.v) v.push_back(to_b2(q, t.s));
  require(t, "a container wall", chain_problem(v, loop));
  b2ChainShape ch;
  if (loop)
    ch.CreateLoop(v.data(), static_cast<int32>(v.size()));
  else
    ch.CreateChain(v.data(), static_cast<int32>(v.size()), to_b2(pc.ghost0, t.s),
                   to_b2(pc.ghost1, t.s));
  ch.m_radius = 0.0f;
  attach(t, ch);
}

// One fixture for a piece, by its kind.
void add_piece(PieceTarget& t, const Piece& pc) {
  switch (pc.kind) {
    case Piece::Kind::kCircle:
      add_circle(t, pc);
      break;
    case Piece::Kind::kPolygon:
      add_polygon(t, pc);
      break;
    case Piece::Kind::kEdge:
      add_edge(t, pc);
      break;
    case Piece::Kind::kChainLoop:
    case Piece::Kind::kChain:
      add_chain(t, pc);
      break;
  }
}

}  // namespace

PluginInfo Box2dBackend::info() {
  PluginInfo i;
  i.name = "box2d";
  i.version = "1.0.0";
  i.doc =
      "Reference backend on Box2D 2.4.1: the sdf backend's obstacles as fixtures of a b2World "
      "(concave polygons decomposed, flippers and sliders as kinematic bodies driven by "
      "velocity), particles as circle bodies; each step the framework's velocities are set, "
      "the world steps with zero gravity, restitution threshold rest_speed and sleeping off, "
      "and positions and velocities are read back. Arcs, intersections and subtractions are "
      "errors, not approximations.";
  i.capabilities = PINSIM_CAP_PARTICLE_CONTACT;
  i.params.push_back(real("length_scale", 0.0)
                         .min(0.0)
                         .units("Box2D units per scene unit")
                         .doc("0: automatic (smallest particle radius becomes 1 unit, moving "
                              "bodies at most 10 units); a step moving a particle more than "
                              "b2_maxTranslation = 2 units is an error"));
  i.params.push_back(integer("velocity_iterations", 8)
                         .min(1)
                         .max(1000)
                         .units("1")
                         .doc("Box2D velocity solver iterations per step"));
  i.params.push_back(integer("position_iterations", 3)
                         .min(1)
                         .max(1000)
                         .units("1")
                         .doc("Box2D position solver iterations per step"));
  i.params.push_back(real("rest_speed", 0.0)
                         .min(0.0)
                         .units("length/s")
                         .doc("restitution threshold: slower impacts get restitution 0 and no "
                              "event (as the sdf backend's rest_speed)"));
  i.params.push_back(integer("curve_segments", 0)
                         .min(0)
                         .max(100000)
                         .units("1")
                         .doc("segments per full circle for the inside of a circle (a concave "
                              "curved wall Box2D cannot express); 0: such walls are an error"));
  return i;
}

Box2dBackend::Box2dBackend(const CreateContext& ctx) {
  const Params& p = ctx.params;
  velocity_iterations_ = static_cast<int>(p.integer("velocity_iterations"));
  position_iterations_ = static_cast<int>(p.integer("position_iterations"));
  rest_speed_ = p.real("rest_speed");
  // The sdf backend's parser validates the whole obstacle format (same errors, same paths)
  // and provides the scripted motion timelines.
  field_ = sdf::ObstacleField(ctx.scene, ctx.context, {}, 0);
  const sdf::ContactOptions contacts = sdf::read_contacts(ctx);
  particle_contacts_ = contacts.particles;
  particle_e_ = contacts.restitution;
  scale_ = choose_length_scale(ctx, field_, p.real("length_scale"));
  // A world without gravity or sleeping; the listener records contacts.
  world_ = std::make_unique<b2World>(b2Vec2(0.0f, 0.0f));
  world_->SetAllowSleeping(false);
  world_->SetContinuousPhysics(true);
  listener_ = std::make_unique<Listener>(this);
  world_->SetContactListener(listener_.get());
  // Obstacles, then particles; Box2D units from here on.
  const float threshold = static_cast<float>(rest_speed_ * scale_);
  add_obstacles(ctx, threshold);
  add_particles(ctx, any_friction(field_), threshold);
  const std::size_t n = ctx.initial.n;
  touched_.assign(n, 0);
  track_t_.assign(n, 0.0);
  track_x_.assign(n, b2Vec2(0.0f, 0.0f));
}

// Obstacles: one body each, with a fixture per convex piece of its shape; fixtures are
// tagged with the obstacle's index.
void Box2dBackend::add_obstacles(const CreateContext& ctx, float threshold) {
  const double s = scale_;
  const BuildOptions bo = build_options(ctx, s);
  for (std::size_t k = 0; k < field_.size(); ++k) {
    const sdf::Obstacle& o = field_.obstacle(k);
    const std::string path = "obstacles[" + std::to_string(k) + "]";
    const b2BodyDef bd = obstacle_body_def(o, s);
    if (const std::string pr = coordinate_problem(bd.position.x, bd.position.y); !pr.empty())
      throw Error(ctx.context + ": " + path + ".motion: unsupported by box2d (obstacle '" + o.id +
                  "'): its body's position " + pr + " at length scale " + num(s));
    b2Body* body = world_->CreateBody(&bd);
    obstacle_body_.push_back(body);
    tags_.push_back({-1, static_cast<int64_t>(k)});
    PieceTarget target{body, b2FixtureDef(), s, ctx.context, path, o.id, thinnest_};
    target.fd.friction = static_cast<float>(o.material.friction);
    target.fd.restitution = static_cast<float>(o.material.restitution);
    target.fd.restitutionThreshold = threshold;
    target.fd.density = 0.0f;
    target.fd.userData.pointer = tags_.size();  // tag index + 1
    const std::vector<Piece> pieces = build_pieces(o.shape, ctx.context, path + ".shape", o.id, bo);
    for (const Piece& pc : pieces) add_piece(target, pc);
    obstacle_fixtures_.push_back(pieces.size());
  }
}

// Particles: circle bodies (static if pinned) whose density gives the particle's mass;
// they pass through each other unless particle contacts are on, and spin only if some
// obstacle has friction.
void Box2dBackend::add_particles(const CreateContext& ctx, bool friction, float threshold) {
  const double s = scale_;
  for (std::size_t i = 0; i < ctx.initial.n; ++i) {
    const auto ii = static_cast<Eigen::Index>(i);
    const double w = ctx.initial.inv_mass[ii];
    const double r = ctx.initial.radius[ii];
    // Box2D's preconditions for the body and its circle
    const std::string where = ctx.context + ": particles[" + std::to_string(i) + "]: ";
    const Vec2 x0 = ctx.initial.x.col(ii);
    if (const std::string pr = coordinate_problem(x0.x() * s, x0.y() * s); !pr.empty())
      throw Error(where + "position " + pr + " at length scale " + num(s));
    if (const std::string pr = coordinate_problem(r * s, 0.0); !pr.empty())
      throw Error(where + "radius " + pr + " at length scale " + num(s));
    if (w > 0.0)
      if (const std::string pr = particle_mass_problem(1.0 / w, r * s, friction); !pr.empty())
        throw Error(where + pr + " (radius " + num(r * s) + " Box2D units at length scale " +
                    num(s) + ")");
    b2BodyDef bd;
    bd.type = w > 0.0 ? b2_dynamicBody : b2_staticBody;
    bd.position = to_b2(ctx.initial.x.col(ii), s);
    bd.fixedRotation = !friction;    // the seed's point-like ball does not spin
    bd.bullet = particle_contacts_;  // continuous collision between particles too
    bd.allowSleep = false;
    b2Body* body = world_->CreateBody(&bd);
    tags_.push_back({static_cast<int64_t>(i), -1});
    b2CircleShape c;
    c.m_radius = static_cast<float>(r * s);
    b2FixtureDef fd;
    fd.shape = &c;
    // Density from the particle's mass (matters for particle-particle contacts only).
    fd.density =
        w > 0.0 ? static_cast<float>((1.0 / w) / (std::numbers::pi * r * s * r * s)) : 0.0f;
    fd.friction = 0.0f;     // set per contact in PreSolve
    fd.restitution = 0.0f;  // set per contact in PreSolve
    fd.restitutionThreshold = threshold;
    fd.userData.pointer = tags_.size();
    if (!particle_contacts_) fd.filter.groupIndex = -1;  // particles pass through each other
    body->CreateFixture(&fd);
    particle_body_.push_back(body);
    last_x_.push_back(ctx.initial.x.col(ii));
  }
}

Box2dBackend::~Box2dBackend() = default;

// Every moving particle's travel this step within b2_maxTranslation (Box2D would silently
// slow it down) and its position within kMaxUnits (beyond, Box2D's floats overflow or
// lose its contacts). The fastest particle is named, with the length scales that would
// take it: below b2_maxTranslation / (v dt), and above b2_linearSlop / (the shortest
// obstacle edge) for the thin walls (check_edges); when the two cross, none.
void Box2dBackend::check_particles(const MutableState& st, double dt) const {
  const double s = scale_;
  double v_max = 0.0;
  std::size_t fastest = st.n, over = 0;
  for (std::size_t i = 0; i < st.n; ++i) {
    const auto ii = static_cast<Eigen::Index>(i);
    if (!(st.inv_mass[ii] > 0.0)) continue;
    const Vec2 x = st.x.col(ii);
    if (const std::string pr = coordinate_problem(x.x() * s, x.y() * s); !pr.empty())
      throw Error("particle " + std::to_string(i) + " at t = " + num(t0_) + ": position " + pr +
                  " at length scale " + num(s));
    const double speed = st.v.col(ii).norm();
    if (!(speed * dt * s <= b2_maxTranslation)) ++over;
    if (!(speed <= v_max)) {  // (a NaN speed is the fastest)
      v_max = speed;
      fastest = i;
    }
  }
  if (over == 0) return;
  const double s_fast = b2_maxTranslation / (v_max * dt);
  const double s_thin = b2_linearSlop / thinnest_.length;
  std::string advice;
  if (!std::isfinite(v_max)) {
    advice = "its velocity is not finite";
  } else if (s_fast > s_thin) {
    advice = "at dt = " + num(dt) + " use the box2d parameter length_scale between " + num(s_thin) +
             " and " + num(s_fast) + " (now " + num(s) + ") or a smaller time step";
  } else {
    advice = "no length scale works at dt = " + num(dt) + ": below " + num(s_fast) +
             " the thinnest wall (an edge of " + num(thinnest_.length) + " in obstacle '" +
             thinnest_.obstacle + "') is shorter than b2_linearSlop; use a time step below " +
             num(b2_maxTranslation / (v_max * s_thin));
  }
  throw Error("particle " + std::to_string(fastest) + " at t = " + num(t0_) + ": speed " +
              num(v_max) + " moves it " + num(v_max * dt * s) +
              " Box2D units in one step, more than b2_maxTranslation = 2 (Box2D would "
              "silently slow it down; " +
              std::to_string(over) + " particle(s) over); " + advice);
}

double Box2dBackend::distance(const Vec2& p, double t, int64_t* obstacle) const {
  const sdf::Nearest nn = field_.nearest(p, t);
  if (obstacle) *obstacle = nn.k;
  return nn.d;
}

double Box2dBackend::vn_now(const Pending& p) const {
  const b2Body* bi = particle_body_[static_cast<std::size_t>(p.e.particle)];
  const b2Vec2 pt = to_b2(Vec2(p.e.point[0], p.e.point[1]), scale_);
  const b2Vec2 vo = p.other->GetLinearVelocityFromWorldPoint(pt);
  const b2Vec2 vi = bi->GetLinearVelocity();
  return (static_cast<double>(vi.x - vo.x) * p.e.normal[0] +
          static_cast<double>(vi.y - vo.y) * p.e.normal[1]) /
         scale_;
}

void Box2dBackend::close_events_of(int64_t particle) {
  for (Pending& p : pending_)
    if (p.open && (p.e.particle == particle || p.e.other == particle)) {
      p.e.vn_after = vn_now(p);
      p.open = false;
    }
}

// One touching contact, before Box2D solves it. Sets the scene's friction and restitution
// (Box2D would mix friction by sqrt(f1 f2) and restitution by max(e1, e2)); records an
// impact when the particle approaches faster than rest_speed. The time of impact is where
// the particle is on its path this step (Box2D's continuous collision has moved it to the
// time of impact, or it is at the step start), moved back by the overlap over the closing
// speed to the first touch.
void Box2dBackend::on_presolve(b2Contact* c) {
  ++stats_.contact_updates;
  b2Fixture* fa = c->GetFixtureA();
  b2Fixture* fb = c->GetFixtureB();
  const Tag& ta = tags_[fa->GetUserData().pointer - 1];
  const Tag& tb = tags_[fb->GetUserData().pointer - 1];
  const bool pair = ta.particle >= 0 && tb.particle >= 0;
  if (ta.particle < 0 && tb.particle < 0) return;
  // i: the particle (the lower index for a pair); the normal points from the other to i
  const bool i_is_a = pair ? ta.particle < tb.particle : ta.particle >= 0;
  const Tag& ti = i_is_a ? ta : tb;
  const Tag& to = i_is_a ? tb : ta;
  b2Body* bi = (i_is_a ? fa : fb)->GetBody();
  b2Body* bo = (i_is_a ? fb : fa)->GetBody();
  if (pair) {
    c->SetFriction(0.0f);
    c->SetRestitution(static_cast<float>(particle_e_));
  } else {
    const sdf::Material& m = field_.obstacle(static_cast<std::size_t>(to.obstacle)).material;
    c->SetFriction(static_cast<float>(m.friction));
    c->SetRestitution(static_cast<float>(m.restitution));
  }
  b2WorldManifold wm;
  c->GetWorldManifold(&wm);
  const int np = c->GetManifold()->pointCount;
  if (np == 0) return;
  b2Vec2 n = wm.normal;  // from A to B
  if (i_is_a) n = -n;
  const auto i = static_cast<std::size_t>(ti.particle);
  touched_[i] = 1;
  if (pair) touched_[static_cast<std::size_t>(to.particle)] = 1;
  const double s = scale_;
  const double sep = wm.separations[0];  // Box2D units, < 0: overlap
  const float ri = bi->GetFixtureList()->GetShape()->m_radius;
  const b2Vec2 ci = bi->GetPosition();
  b2Vec2 pt;
  if (pair)
    pt = bo->GetPosition() + bo->GetFixtureList()->GetShape()->m_radius * n;
  else
    pt = ci - (ri + static_cast<float>(sep)) * n;
  const b2Vec2 vi = bi->GetLinearVelocity();
  const b2Vec2 vo = bo->GetLinearVelocityFromWorldPoint(pt);
  const double vn =
      (static_cast<double>(vi.x - vo.x) * n.x + static_cast<double>(vi.y - vo.y) * n.y) / s;

  for (Pending& p : pending_) {
    if (p.contact == c && p.open) {
      if (vn >= 0.0) {  // this impact has been resolved: its outgoing normal velocity
        p.e.vn_after = vn;
        p.open = false;
      }
      return;  // still the same impact
    }
  }
  close_events_of(static_cast<int64_t>(i));
  if (pair) close_events_of(to.particle);
  if (!(vn < 0.0) || -vn < rest_speed_) return;

  auto path_time = [&](std::size_t k, const b2Body* b) {
    const b2Vec2 d = b->GetPosition() - track_x_[k];
    const b2Vec2 v = b->GetLinearVelocity();
    const double vv = static_cast<double>(v.x) * v.x + static_cast<double>(v.y) * v.y;
    double tau = track_t_[k];
    if (vv > 0.0)
      tau += std::max(0.0, (static_cast<double>(d.x) * v.x + static_cast<double>(d.y) * v.y) / vv);
    tau = std::clamp(tau, t0_, t0_ + dt_);
    track_t_[k] = tau;
    track_x_[k] = b->GetPosition();
    return tau;
  };
  double tau = path_time(i, bi);
  if (pair) tau = std::max(tau, path_time(static_cast<std::size_t>(to.particle), bo));
  // A contact found at the step start was crossed during the previous step (too shallow
  // for Box2D's time of impact, whose target is 3 slop deep): its first touch lies there.
  if (sep < 0.0) tau = std::max(t0_ - dt_, tau - (-sep / s) / (-vn));

  Pending pd;
  pd.contact = c;
  pd.other = bo;
  pinsim_event& e = pd.e;
  e.t = tau;
  e.particle = ti.particle;
  e.obstacle = pair ? -1 : to.obstacle;
  e.other = pair ? to.particle : -1;
  const Vec2 ps = from_b2(pt, s);
  e.point[0] = ps.x();
  e.point[1] = ps.y();
  e.normal[0] = n.x;
  e.normal[1] = n.y;
  e.vn_before = vn;
  e.vn_after = vn;
  pending_.push_back(pd);
}

void Box2dBackend::advance(MutableState& st, double dt, EventSink& ev) {
  if (!(dt > 0.0)) return;
  const double s = scale_;
  t0_ = st.t;
  dt_ = dt;
  // Kinematic obstacles: the velocity that takes the body from its present pose to the
  // scripted pose at the end of the step (never SetTransform; the float pose is corrected
  // every step, so it does not drift from the script).
  for (uint32_t k : field_.moving()) {
    const sdf::Obstacle& o = field_.obstacle(k);
    b2Body* b = obstacle_body_[k];
    if (o.motion == sdf::MotionType::kFlipper) {
      const double w = (o.timeline->value(t0_ + dt) - static_cast<double>(b->GetAngle())) / dt;
      if (std::abs(w * dt) > b2_maxRotation)
        throw Error("obstacle '" + o.id + "' turns " + num(w * dt) +
                    " rad in one step, more than Box2D's b2_maxRotation = " + num(b2_maxRotation));
      b->SetAngularVelocity(static_cast<float>(w));
    } else {
      const Vec2 target = o.timeline->value(t0_ + dt) * o.offset * s;
      const b2Vec2 at = b->GetPosition();
      const Vec2 v = (target - Vec2(at.x, at.y)) / dt;
      if (v.norm() * dt > b2_maxTranslation)
        throw Error("obstacle '" + o.id +
                    "' moves more than Box2D's b2_maxTranslation in one step");
      b->SetLinearVelocity(b2Vec2(static_cast<float>(v.x()), static_cast<float>(v.y())));
    }
  }
  check_particles(st, dt);
  for (std::size_t i = 0; i < st.n; ++i) {
    const auto ii = static_cast<Eigen::Index>(i);
    if (!(st.inv_mass[ii] > 0.0)) continue;
    b2Body* b = particle_body_[i];
    const Vec2 x = st.x.col(ii), v = st.v.col(ii);
    const b2Vec2 xb = to_b2(x, s);
    if (!(b->GetPosition() == xb)) b->SetTransform(xb, b->GetAngle());
    b->SetLinearVelocity(to_b2(v, s));
    touched_[i] = 0;
    track_t_[i] = t0_;
    track_x_[i] = xb;
  }
  pending_.clear();
  world_->Step(static_cast<float>(dt), velocity_iterations_, position_iterations_);
  ++stats_.steps;

  for (Pending& p : pending_)
    if (p.open) {
      p.e.vn_after = vn_now(p);
      p.open = false;
    }
  for (std::size_t i = 0; i < st.n; ++i) {
    const auto ii = static_cast<Eigen::Index>(i);
    if (!(st.inv_mass[ii] > 0.0)) continue;
    if (touched_[i]) {
      // Box2D resolved a contact: its (float) result is the answer.
      st.x.col(ii) = from_b2(particle_body_[i]->GetPosition(), s);
      st.v.col(ii) = from_b2(particle_body_[i]->GetLinearVelocity(), s);
    } else {
      // Free flight: Box2D's own x += h v in float; the exact double drift is the same
      // motion without float rounding.
      st.x.col(ii) += dt * st.v.col(ii);
      ++stats_.free_flights;
    }
  }
  // Bumper kicks: the speed added along the normal at the time of impact (sdf semantics),
  // applied after the solve, with the distance it would have added since the impact.
  std::stable_sort(pending_.begin(), pending_.end(),
                   [](const Pending& a, const Pending& b) { return a.e.t < b.e.t; });
  for (Pending& p : pending_) {
    if (p.e.obstacle >= 0) {
      const double kick = field_.obstacle(static_cast<std::size_t>(p.e.obstacle)).material.kick;
      if (kick > 0.0) {
        const Vec2 nrm(p.e.normal[0], p.e.normal[1]);
        const auto ii = static_cast<Eigen::Index>(p.e.particle);
        st.v.col(ii) += kick * nrm;
        st.x.col(ii) += kick * (t0_ + dt - p.e.t) * nrm;
        p.e.vn_after += kick;
      }
    }
    ++stats_.events;
    ev.emit(p.e);
  }
  for (std::size_t i = 0; i < st.n; ++i) last_x_[i] = st.x.col(static_cast<Eigen::Index>(i));
}

}  // namespace pinsim::box2d
