#include "sdf_backend.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <pinsim/parallel.hpp>
#include <pinsim/scene_field/limits.hpp>

#include "contact_options.hpp"

namespace pinsim::sdf {

PluginInfo SdfBackend::info() {
  PluginInfo i;
  i.name = "sdf";
  i.version = "1.0.0";
  i.doc =
      "Signed-distance-field obstacles (circle, box, rounded box, capsule, tapered capsule, "
      "polygon, arc, half-plane, union/intersection/subtraction, containers) with continuous "
      "collision by sphere tracing sdf - r along each particle's path, impulses v' = v - "
      "(1+e)(v_rel.n)n at the time of impact, scripted flippers and sliders, optional "
      "particle-particle contacts.";
  i.capabilities = PINSIM_CAP_PARTICLE_CONTACT | PINSIM_CAP_DIFFERENTIABLE;
  i.params.push_back(real("depth_min", 1e-5)
                         .min(0.0, true)
                         .units("length")
                         .doc("contact offset: the march stops this far from the surface, so a "
                              "resting particle neither sinks nor chatters"));
  i.params.push_back(real("march_tolerance", 0.1)
                         .min(0.0, true)
                         .max(1.0)
                         .units("1")
                         .doc("the march ends within this fraction of depth_min above the offset"));
  i.params.push_back(
      integer("max_collisions", 16)
          .min(1)
          .max(1e6)
          .units("1")
          .doc("impulses per particle per step; on reaching it the particle stays at its last safe "
               "position for the rest of the step"));
  i.params.push_back(
      integer("max_iterations", 200)
          .min(1)
          .max(1e7)
          .units("1")
          .doc("march iterations per particle per step; same fallback as max_collisions"));
  i.params.push_back(
      real("rest_speed", 0.0)
          .min(0.0)
          .units("length/s")
          .doc("impacts slower than this are resting contacts: restitution 0, no kick, no event"));
  i.params.push_back(integer("grid_cells", 16384)
                         .min(0)
                         .max(1e7)
                         .units("1")
                         .doc("target cell count of the grid over static obstacles (0: no grid)"));
  return i;
}

SdfBackend::SdfBackend(const CreateContext& ctx)
    : FieldBackend(ctx, ctx.params.integer("grid_cells"), "sdf backend") {
  const Params& p = ctx.params;
  depth_min_ = p.real("depth_min");
  tol_ = p.real("march_tolerance") * depth_min_;
  max_collisions_ = static_cast<int>(p.integer("max_collisions"));
  max_iterations_ = static_cast<int>(p.integer("max_iterations"));
  rest_speed_ = p.real("rest_speed");
  const ContactOptions contacts = read_contacts(ctx);
  particle_contacts_ = contacts.particles;
  particle_e_ = contacts.restitution;
  reset_timeline_caches();
}

void SdfBackend::reset_timeline_caches() {
  speed_bound_.assign(field_.size(), 0.0);
  timeline_hint_.assign(field_.size(), 0);
  last_segment_.assign(field_.size(), 0);
  rest_ = RestCache{};  // no records and no still epoch, as in a new backend
}

void SdfBackend::input(const std::string& name, bool pressed, double t) {
  FieldBackend::input(name, pressed, t);
  reset_timeline_caches();
}

namespace {
/// The event of an impulse on particle i from obstacle k at time t: contact point pc,
/// normal n, normal relative speed before and after.
[[gnu::always_inline]] inline pinsim_event impact_event(std::size_t i, int64_t k, double t,
                                                        const Vec2& pc, const Vec2& n,
                                                        double vn_before, double vn_after) {
  pinsim_event e{};
  e.t = t;
  e.particle = static_cast<int64_t>(i);
  e.obstacle = k;
  e.other = -1;
  e.point[0] = pc.x();
  e.point[1] = pc.y();
  e.normal[0] = n.x();
  e.normal[1] = n.y();
  e.vn_before = vn_before;
  e.vn_after = vn_after;
  return e;
}
}  // namespace

// Sphere tracing (conservative advancement). Along the path x(s) = x + v s the clearance
// d(s) = min_k sdf_k(x(s), t + s) - r changes at most at L = |v| + U, U the largest speed of
// a nearby moving obstacle (an exact SDF is 1-Lipschitz in space; a rigid motion moves the
// field at a fixed point by at most the speed of its fastest point). So the path is free of
// contact for s < (d - depth_min) / L, and that is the step. Within the band
// d <= depth_min + tol the nearest obstacle's normal n = grad sdf and its velocity u at the
// contact point decide: approaching ((v - u).n < 0) gives the impulse
//   v' = v - (1 + e)((v - u).n) n  - min(mu j, |v_t|) t̂  + kick n,
// otherwise the particle moves on by at most max(d, depth_min), which cannot take it deeper
// than depth_min inside the surface.
[[gnu::always_inline]] inline SdfBackend::MarchEnd SdfBackend::march_path(std::size_t i, Vec2& x,
                                                                          Vec2& v, double r,
                                                                          double t, double dur,
                                                                          Budget& b, EventSink& ev,
                                                                          RestProbe* probe) {
  double remaining = dur;
  const auto& moving = field_.moving();
  bool first = true;
  bool in_band = false;  ///< the last query was in the contact band
  bool entered = false;  ///< the last move was a sphere-tracing step from outside the band
  while (remaining > 0.0) {
    if (b.iterations >= max_iterations_ || b.collisions >= max_collisions_) {
      // Fallback: for the rest of the step the particle rides rigidly with the nearest
      // obstacle (stays where it is if that one is static); its velocity is kept.
      const Nearest nn = field_.nearest(x, t);
      if (nn.k >= 0) x = field_.carry(static_cast<std::size_t>(nn.k), x, t, t + remaining);
      return MarchEnd::capped;
    }
    ++b.iterations;
    // after a query in the contact band the next is likely there too: take the gradient
    // with the query rather than evaluating the nearest obstacle again
    const Nearest nn = in_band ? field_.nearest_with_gradient(x, t) : field_.nearest(x, t);
    if (nn.k < 0) {
      x += v * remaining;
      return MarchEnd::arrived;
    }
    const double d = nn.d - r;
    const double speed = v.norm();
    double u_max = 0.0;
    for (uint32_t k : moving) {
      const double uk = speed_bound_[k];
      if (uk > 0.0 && field_.lower_bound(k, x) - r - depth_min_ <= (speed + uk) * remaining)
        u_max = std::max(u_max, uk);
    }
    if (probe)
      probe->observe(x, nn.d, speed,
                     u_max > 0.0 || field_.obstacle(static_cast<std::size_t>(nn.k)).motion !=
                                        MotionType::kStatic);
    const double lip = speed + u_max;
    if (!(lip > 0.0)) return MarchEnd::arrived;  // nothing moves relative to anything
    if (d > depth_min_ + tol_) {
      in_band = false;
      const double step = (d - depth_min_) / lip;
      if (step >= remaining) {
        x += v * remaining;
        return first ? MarchEnd::skipped : MarchEnd::arrived;
      }
      x += v * step;
      t += step;
      remaining -= step;
      first = false;
      entered = true;
      continue;
    }
    first = false;
    const auto k = static_cast<std::size_t>(nn.k);
    Sdf sd = in_band ? Sdf{nn.d, nn.g} : field_.eval(k, x, t);
    in_band = true;
    Vec2 n = sd.g;
    Vec2 pc = x - sd.d * n;
    Vec2 u = field_.velocity(k, pc, t);
    Vec2 vr = v - u;
    double vn = vr.dot(n);
    // approaching, beyond rounding of an earlier impulse
    auto approaching = [&] { return vn < -1e-12 * (v.norm() + u.norm()); };
    bool toi = entered;  // the impulse's time is a root of phi = offset (drift_recorder.hpp)
    entered = false;
    if (approaching() && d > depth_min_) {
      toi = true;
      // The march stopped up to tol above the offset: move on to the time of impact by
      // the linear estimate (d - depth_min) / -vn, never more than the safe step d / L.
      const double s = std::min({(d - depth_min_) / -vn, d / lip, remaining});
      x += v * s;
      t += s;
      remaining -= s;
      sd = field_.eval(k, x, t);
      n = sd.g;
      pc = x - sd.d * n;
      u = field_.velocity(k, pc, t);
      vr = v - u;
      vn = vr.dot(n);
    }
    const double dc = sd.d - r;
    if (approaching()) {
      const Material& m = field_.obstacle(k).material;
      const bool resting = -vn < rest_speed_;
      const double jn = -(1.0 + (resting ? 0.0 : m.restitution)) * vn;
      Vec2 dv = jn * n;
      if (m.friction > 0.0) {
        const Vec2 vt = vr - vn * n;
        const double vtn = vt.norm();
        if (vtn > 0.0) dv -= std::min(m.friction * jn, vtn) / vtn * vt;
      }
      if (!resting && m.kick > 0.0) dv += m.kick * n;
      if (tape_.on())
        tape_.impact(field_, i, k, toi, t, x, v, v + dv, r + depth_min_, resting, !resting);
      v += dv;
      ++b.collisions;
      if (!resting) ev.emit(impact_event(i, nn.k, t, pc, n, vn, (v - u).dot(n)));
      if (dc < depth_min_) x += (depth_min_ - dc) * n;  // back to the contact offset
      if (u_max == 0.0 && v.squaredNorm() == 0.0) {     // at rest, nothing nearby moves
        if (probe) probe->at_rest = resting && b.collisions == 1;
        return MarchEnd::arrived;
      }
      continue;
    }
    if (tape_.on() && !(vn > 1e-6 * (v.norm() + u.norm())))  // moving along the surface
      tape_.finding(PINSIM_FINDING_TOUCH, i, nn.k, t, vn);
    double step = std::max(dc, depth_min_) / lip;
    if (step < remaining) step = std::max(step, slide_step(k, x, v, r, remaining, lip));
    if (step >= remaining) {
      x += v * remaining;
      return MarchEnd::arrived;
    }
    x += v * step;
    t += step;
    remaining -= step;
  }
  return MarchEnd::arrived;
}

// The march's statistics: its queries and impulses are counted in the budget on the way and
// added here, with a cap hit or a skip, when the path ends.
bool SdfBackend::march(std::size_t i, Vec2& x, Vec2& v, double r, double t, double dur, Budget& b,
                       SdfStats& st, EventSink& ev, RestProbe* probe) {
  const Budget before = b;
  const MarchEnd end = march_path(i, x, v, r, t, dur, b, ev, probe);
  st.queries += static_cast<uint64_t>(b.iterations - before.iterations);
  st.contacts += static_cast<uint64_t>(b.collisions - before.collisions);
  st.cap_hits += end == MarchEnd::capped;
  st.skipped += end == MarchEnd::skipped;
  if (end == MarchEnd::capped && tape_.on())
    tape_.finding(PINSIM_FINDING_CAP_HIT, i, -1, t, b.collisions);
  return end != MarchEnd::capped;
}

// Sliding on a static obstacle k (in the band, not approaching): the steps above move
// max(d, depth_min) / L at a time, about depth_min each. Instead the path x + v s,
// s <= remaining, is taken whole if k's SDF stays at least r + depth_min / 2 along it
// (ShapeTree::segment_bounds: exact or by convexity, so a wall curving towards the path is
// seen), cut at (c - r - depth_min) / L by the clearance c to every other obstacle (sphere
// tracing them as above; moving ones by their time-independent lower bound). 0 if it does
// not apply; only tried when it saves a few of the short steps.
double SdfBackend::slide_step(std::size_t k, const Vec2& x, const Vec2& v, double r,
                              double remaining, double lip) const {
  if (field_.obstacle(k).motion != MotionType::kStatic || remaining * lip < 4.0 * depth_min_)
    return 0.0;
  if (!(field_.segment_lower_bound(k, x, x + v * remaining) - r >= 0.5 * depth_min_)) return 0.0;
  const double c = field_.clearance_except(k, x) - r - depth_min_;
  return c > 0.0 ? std::min(remaining, c / lip) : 0.0;
}

// Particle-particle contacts, one pass per step (pair_contacts.cpp): candidate pairs (boxes
// swept during the step that overlap) from a kept list of nearby pairs; for each pair the time of
// impact tau of two discs in linear motion; pairs handled in order of tau with the velocities as
// updated by earlier pairs, each impulse J = -(1 + e) vn / (w_i + w_j) (w = inverse masses)
// becoming a velocity change at tau that the obstacle march applies on the way. Obstacle contacts
// inside the step do not re-schedule pairs.
void SdfBackend::resolve_pairs(const MutableState& s, double dt, bool threads, EventSink& ev) {
  pairs_.resolve_found(s, dt, particle_e_, threads, ev);
  stats_.pair_contacts += pairs_.counts().impulses;
}

// Speed bounds of the moving obstacles over the step (each timeline keeps its segment as a
// hint), whether none moves, and whether each stays in the segment of the step before.
// This and the two stages below are always inlined into advance, which runs them once per
// step or once per particle step.
[[gnu::always_inline]] inline SdfBackend::ObstacleMotion SdfBackend::bound_moving_obstacles(
    double t0, double dt) {
  ObstacleMotion m;
  for (uint32_t k : field_.moving()) {
    speed_bound_[k] = field_.speed_bound(k, t0, t0 + dt, timeline_hint_[k]);
    m.still = m.still && speed_bound_[k] == 0.0;
    m.same_segments = m.same_segments && last_segment_[k] == timeline_hint_[k];
    last_segment_[k] = timeline_hint_[k];
  }
  return m;
}

// Particle i over the step, marched between its pair contacts' velocity changes with one
// budget for the whole step; without any, as march_or_reuse (the same march).
[[gnu::always_inline]] inline void SdfBackend::march_with_changes(std::size_t i, MutableState& s,
                                                                  double t0, double dt,
                                                                  SdfStats& st, EventSink& ev) {
  if (!pairs_.changed(i) && !tape_.on()) {  // recording: every particle marched
    march_or_reuse(i, s, t0, dt, st, ev);
    return;
  }
  Vec2 x = s.x.col(i), v = s.v.col(i);
  const double r = s.radius[i];
  ++st.particle_steps;
  Budget b;
  double done = 0.0;
  std::size_t k = 0;
  for (const PairContacts::Change& c : pairs_.changes(i)) {
    march(i, x, v, r, t0 + done, c.tau - done, b, st, ev);
    if (tape_.on()) tape_.change(i, k++, c.tau, x, v, v + c.dv);
    v += c.dv;
    done = c.tau;
  }
  march(i, x, v, r, t0 + done, dt - done, b, st, ev);
  s.x.col(i) = x;
  s.v.col(i) = v;
}

// Particle i over the step without pair contacts. At rest, with an input seen before and
// the same obstacles in reach: the same output and counters as the recorded step.
// Otherwise the march, with a probe of what it looked at; a step that ended at rest on
// static obstacles, or while nothing moves, is recorded.
[[gnu::always_inline]] inline void SdfBackend::march_or_reuse(std::size_t i, MutableState& s,
                                                              double t0, double dt, SdfStats& st,
                                                              EventSink& ev) {
  Vec2 x = s.x.col(i), v = s.v.col(i);
  const double r = s.radius[i];
  const RestRecord* hit = rest_.find(i, x, v, r, dt);
  if (hit != nullptr && rest_.reusable(*hit, field_, speed_bound_, depth_min_)) {
    add(st, hit->added);
    ++st.reuses;
    s.x.col(i) = hit->x_out;
    s.v.col(i) = hit->v_out;
    return;
  }
  const SdfStats before = st;
  ++st.particle_steps;
  RestProbe probe;
  probe.x0 = x;
  Budget b;
  march(i, x, v, r, t0, dt, b, st, ev, &probe);
  if (probe.at_rest && (probe.static_only || rest_.still()))
    rest_.store(i, hit,
                {s.x.col(i), s.v.col(i), x, v, r, dt, std::sqrt(probe.reach), probe.d_max,
                 probe.speed, st - before, rest_.epoch(), !probe.static_only});
  else
    rest_.forget(i);
  s.x.col(i) = x;
  s.v.col(i) = v;
}

namespace {
void push_event(void* ctx, const pinsim_event* e) {
  static_cast<std::vector<pinsim_event>*>(ctx)->push_back(*e);
}

/// Waits (spinning) until ready() holds, true, or until `stop` is set or kSpinLimit has
/// passed, false: for waits on a thread that is running, never on work that may be queued
/// behind the waiting thread.
template <class Ready>
bool spin_until(Ready&& ready, const std::atomic<bool>& stop) {
  constexpr std::chrono::microseconds kSpinLimit{50};
  std::chrono::steady_clock::time_point until{};
  for (unsigned turn = 0;; ++turn) {
    if (stop.load(std::memory_order_acquire)) return false;
    if (ready()) return true;
    if (turn % 64 == 0) {
      const auto now = std::chrono::steady_clock::now();
      if (turn == 0)
        until = now + kSpinLimit;
      else if (now > until)
        return false;
    }
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
  }
}
}  // namespace

// Fixed chunks of kChunk particles, on threads: each chunk's events collected apart in
// events[c] (in particle order), its counters added to chunk_stats_[c] once.
template <class Particle>
void SdfBackend::march_chunked(std::size_t n, Particle&& particle,
                               std::vector<std::vector<pinsim_event>>& events) {
  events.resize(chunk_count(n, kChunk));
  for_chunks(n, kChunk, [&](std::size_t c, std::size_t b, std::size_t e) {
    events[c].clear();
    const pinsim_event_sink to{&events[c], &push_event};
    EventSink sink(&to);
    SdfStats st;  // counted here, stored once: chunks next to each other share cache lines
    for (std::size_t i = b; i < e; ++i) particle(i, st, sink);
    add(chunk_stats_[c], st);
  });
}

std::size_t SdfBackend::too_fast(const MutableState& s, double dt, bool threads) {
  // the first particle of [b, e) with finite mass moving beyond the limit, else e
  const double* v = s.v.data();  // (plain pointers: no reloads of the maps' members)
  const double* w = s.inv_mass.data();
  auto first = [=](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      if (!(w[i] > 0.0)) continue;  // pinned particles do not move
      if (travels_beyond(v[2 * i], v[2 * i + 1], dt)) return i;
    }
    return e;
  };
  if (!threads) return first(0, s.n);
  first_too_fast_.assign(chunk_count(s.n, kParticleChunk), s.n);
  for_chunks(
      s.n, kParticleChunk,
      [&](std::size_t c, std::size_t b, std::size_t e) {
        if (const std::size_t i = first(b, e); i < e) first_too_fast_[c] = i;
      },
      Schedule::Even);
  for (const std::size_t i : first_too_fast_)
    if (i < s.n) return i;
  return s.n;
}

void SdfBackend::advance(MutableState& s, double dt, EventSink& ev) {
  if (!(dt > 0.0)) return;
  const double t0 = s.t;
  if (tape_.on()) tape_.begin(s, dt);
  // The obstacles' motion over the step, then the pair contacts within it.
  const ObstacleMotion motion = bound_moving_obstacles(t0, dt);
  rest_.begin_step(motion.still, motion.same_segments);
  // (beyond the limit the march cannot resolve the step: refuse, never freeze silently;
  // checked for every particle before any moves or meets another, so a refused step changes
  // nothing; in fixed chunks on threads for large states, the first offender in particle
  // order named; while recording drifts, one by one in particle order. With pair contacts
  // their first pass over the particles checks, before it finds any hit.)
  const bool threads = !tape_.on() && s.n >= kParallelParticles && available_threads() > 1;
  const bool pairs = particle_contacts_ && s.n > 1;
  const std::size_t fast =
      pairs ? pairs_.find(s, dt, threads, tape_.on() ? &tape_ : nullptr, kMaxMagnitude)
            : too_fast(s, dt, threads);
  if (const std::size_t i = fast; i < s.n)
    throw Error("particle " + std::to_string(i) + " at t = " + num(t0) + " s: velocity (" +
                num(s.v(0, i)) + ", " + num(s.v(1, i)) +
                ") travels beyond the sdf backend's limit of 1e+09 per step "
                "(backends/sdf/README.md, Limits)");
  if (pairs && threads) {
    march_beside_pairs(s, t0, dt, ev);
    return;
  }
  if (pairs)
    resolve_pairs(s, dt, threads, ev);
  else if (tape_.on())
    pairs_.clear(s.n);  // recording: every particle through march_with_changes
  // Each particle with finite mass along its path, contacts resolved on the way. Particles
  // are independent here (pair contacts are fixed above as velocity changes in pairs_,
  // the rest cache keeps one record set per particle, the field is only read), so fixed
  // chunks of them may run on threads; each chunk counts and collects its events apart, and
  // they are added and emitted in chunk order: the serial order, for any thread count.
  rest_.resize(s.n);
  auto particle = [&](std::size_t i, SdfStats& st, EventSink& sink) {
    if (!(s.inv_mass[i] > 0.0)) return;  // pinned particles do not move
    if (pairs || tape_.on())
      march_with_changes(i, s, t0, dt, st, sink);
    else
      march_or_reuse(i, s, t0, dt, st, sink);
  };
  if (!threads) {
    for (std::size_t i = 0; i < s.n; ++i) particle(i, stats_, ev);
    return;
  }
  const std::size_t chunks = chunk_count(s.n, kChunk);
  chunk_stats_.assign(chunks, SdfStats{});
  march_chunked(s.n, particle, chunk_events_);
  for (std::size_t c = 0; c < chunks; ++c) {
    add(stats_, chunk_stats_[c]);
    for (const pinsim_event& e : chunk_events_[c]) ev.emit(e);
  }
}

// A particle in no hit of the step gets no velocity change from the pair contacts, so its
// march (march_or_reuse, as in the serial loop) does not wait for them: one side, on the
// calling thread, orders and resolves the hits and emits their events (on one thread, each as
// its hit fires; from three, its waves on several, the events after) while the others march
// those particles in fixed chunks. A particle in hits may be marched once its last hit is resolved:
// while the serial resolution runs, the marching thread goes on with the particles in hits of the
// chunks it is past (resolved_below()), keeping those in a hit that does not touch at the start
// apart; it stops when the resolution ends or when it has waited 50 us for the next chunk. Then
// every chunk's particles left, on threads. A particle's march reads only its own changes,
// so it gives the same bits whenever and wherever it runs after its last hit. Each chunk's
// events are kept in lists by particle and emitted after the pair events, the chunks' lists
// merged by particle (a particle is in one): the order of the serial loop, for any thread
// count.
void SdfBackend::march_beside_pairs(MutableState& s, double t0, double dt, EventSink& ev) {
  rest_.resize(s.n);
  const std::size_t chunks = chunk_count(s.n, kChunk);
  chunk_stats_.assign(chunks, SdfStats{});
  late_stats_.assign(chunks, SdfStats{});
  late_events_.resize(chunks);
  kept_apart_.resize(chunks);
  late_mark_.assign(chunks, 0);
  marched_early_.assign(chunks, 0);
  auto march_into = [&](std::size_t c, std::size_t i, SdfStats& st) {
    const pinsim_event_sink to{&late_events_[c], &push_event};
    EventSink sink(&to);
    march_with_changes(i, s, t0, dt, st, sink);
  };
  // chunk c's particles in hits, those in a hit that does not touch at the start kept apart
  // unless every hit is resolved (`all`)
  auto march_hits = [&](std::size_t c, bool all) {
    late_events_[c].clear();
    kept_apart_[c].clear();
    SdfStats st;
    for (std::size_t i = c * kChunk, e = std::min(s.n, i + kChunk); i < e; ++i) {
      if (!(s.inv_mass[i] > 0.0) || !pairs_.in_hit(i)) continue;
      if (!all && pairs_.late(i))
        kept_apart_[c].push_back(static_cast<uint32_t>(i));
      else
        march_into(c, i, st);
    }
    late_stats_[c] = st;
    late_mark_[c] = late_events_[c].size();
  };
  auto free_one = [&](std::size_t i, SdfStats& st, EventSink& sink) {
    if (s.inv_mass[i] > 0.0 && !pairs_.in_hit(i)) march_or_reuse(i, s, t0, dt, st, sink);
  };
  std::atomic<bool> resolved{false};
  run_both(
      [&] {
        // (from three threads its waves may use the others; isolated, so that this thread
        // never runs the other side's work beneath them)
        struct Done {  // (also if this side throws: the marching side stops waiting)
          std::atomic<bool>& flag;
          ~Done() { flag.store(true, std::memory_order_release); }
        } done{resolved};
        if (available_threads() > 2)
          isolated([&] { pairs_.resolve_found(s, dt, particle_e_, true, ev); });
        else
          pairs_.resolve_found(s, dt, particle_e_, false, ev);
      },
      [&] {
        march_chunked(s.n, free_one, chunk_events_);
        for (std::size_t c = 0; c < chunks; ++c) {
          const std::size_t e = std::min(s.n, (c + 1) * kChunk);
          if (!spin_until([&] { return pairs_.resolved_below() >= e; }, resolved)) return;
          march_hits(c, pairs_.resolved_below() == PairContacts::kAllResolved);
          marched_early_[c] = 1;
        }
      });
  for_chunks(chunks, 1, [&](std::size_t c, std::size_t, std::size_t) {
    if (marched_early_[c] == 0) {
      march_hits(c, true);
      return;
    }
    if (kept_apart_[c].empty()) return;
    SdfStats st;  // (counted here, added once: neighbouring chunks share cache lines)
    for (const uint32_t i : kept_apart_[c]) march_into(c, i, st);
    add(late_stats_[c], st);
    auto& late = late_events_[c];
    std::inplace_merge(
        late.begin(), late.begin() + static_cast<std::ptrdiff_t>(late_mark_[c]), late.end(),
        [](const pinsim_event& a, const pinsim_event& b) { return a.particle < b.particle; });
  });
  stats_.pair_contacts += pairs_.counts().impulses;
  for (std::size_t c = 0; c < chunks; ++c) {
    add(stats_, chunk_stats_[c]);
    add(stats_, late_stats_[c]);
    const auto& early = chunk_events_[c];
    const auto& late = late_events_[c];
    auto a = early.cbegin(), b = late.cbegin();
    while (a != early.cend() || b != late.cend())
      ev.emit(b == late.cend() || (a != early.cend() && a->particle < b->particle) ? *a++ : *b++);
  }
}

}  // namespace pinsim::sdf
