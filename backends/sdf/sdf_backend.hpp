// SdfBackend: continuous collision of disc particles against SDF obstacles by sphere
// tracing, with impulses at the time of impact, moving obstacles and optional
// particle-particle contacts.
#pragma once

#include <cstdint>
#include <pinsim/plugin.hpp>
#include <pinsim/scene_field.hpp>
#include <string>
#include <vector>

#include "drift_recorder.hpp"
#include "pair_contacts.hpp"
#include "rest_cache.hpp"
#include "sdf_stats.hpp"

namespace pinsim::sdf {

/// The obstacles, distance() and outline() come from the SDK's scene field (FieldBackend);
/// input() also resets the caches that depend on the timelines.
class SdfBackend : public FieldBackend {
 public:
  static PluginInfo info();
  explicit SdfBackend(const CreateContext& ctx);

  /// Moves every particle with finite mass along its velocity over [s.t, s.t + dt],
  /// resolving each contact at its time of impact.
  void advance(MutableState& s, double dt, EventSink& ev);
  /// Input `name` pressed or released at time t, between steps: the obstacles listening to
  /// it get the event on their timelines, and every cache that depends on the timelines is
  /// reset, so the run continues bit-identical to a backend created with the event in its
  /// scene's "inputs". Throws Error naming an unknown input.
  void input(const std::string& name, bool pressed, double t);
  /// Report every drift to `sink` for the adjoint of a run (null: stop); while recording,
  /// particles are marched one by one without the rest cache (the same bits).
  void record_drift(const pinsim_drift_sink* sink) { tape_.set(sink); }
  const SdfStats& stats() const { return stats_; }
  /// What the last step's pair contacts found (particle contacts on).
  const PairContacts::Counts& pair_counts() const { return pairs_.counts(); }
  double depth_min() const { return depth_min_; }
  double march_tolerance() const { return tol_; }

 private:
  struct Budget {
    int collisions = 0;
    int iterations = 0;
  };
  /// Moves particle i from (x, v) at time t over `dur`; false if the caps stopped it early.
  /// Counts into st and emits into ev (the chunk's own when particles run on threads).
  bool march(std::size_t i, Vec2& x, Vec2& v, double r, double t, double dur, Budget& b,
             SdfStats& st, EventSink& ev, RestProbe* probe = nullptr);
  /// How a march's path ended: at the end of `dur` (or at rest), in one step (its first
  /// query's clearance exceeded the travel), or at a cap (the fallback took the rest).
  enum class MarchEnd { arrived, skipped, capped };
  /// The path of march(): the sphere tracing and the impulses, counted in b.
  MarchEnd march_path(std::size_t i, Vec2& x, Vec2& v, double r, double t, double dur, Budget& b,
                      EventSink& ev, RestProbe* probe);
  /// Step along a sliding contact with static obstacle k (see sdf_backend.cpp), 0 if none.
  double slide_step(std::size_t k, const Vec2& x, const Vec2& v, double r, double remaining,
                    double lip) const;
  /// What the moving obstacles do over a step.
  struct ObstacleMotion {
    bool still = true;          ///< none moves (every speed bound 0)
    bool same_segments = true;  ///< every timeline is in the segment of the step before
  };
  /// Speed bounds of the moving obstacles over [t0, t0 + dt], and their motion.
  ObstacleMotion bound_moving_obstacles(double t0, double dt);
  /// Particle i of s through the step with the velocity changes of its pair contacts.
  void march_with_changes(std::size_t i, MutableState& s, double t0, double dt, SdfStats& st,
                          EventSink& ev);
  /// Particle i of s through the step without pair contacts: reused from the rest cache
  /// when it can be, else marched (and remembered if it ended at rest).
  void march_or_reuse(std::size_t i, MutableState& s, double t0, double dt, SdfStats& st,
                      EventSink& ev);
  /// Forgets what the steps so far learned about the timelines (speed bounds, segment
  /// hints, still epochs, rest records), as a newly created backend has.
  void reset_timeline_caches();
  /// Particle-particle contacts within the step, their hits found (pairs_.find()):
  /// resolved into pairs_ (see README) and their events emitted, on threads if `threads`.
  void resolve_pairs(const MutableState& s, double dt, bool threads, EventSink& ev);
  /// The step on threads with pair contacts, their hits found: the particles in no hit
  /// marched while the hits are resolved, the others as soon as their hits are.
  void march_beside_pairs(MutableState& s, double t0, double dt, EventSink& ev);
  /// particle(i, stats, sink) for particles 0..n-1 in fixed chunks on threads (events[c],
  /// chunk_stats_[c]: per chunk).
  template <class Particle>
  void march_chunked(std::size_t n, Particle&& particle,
                     std::vector<std::vector<pinsim_event>>& events);

  double depth_min_ = 1e-5;  ///< contact offset ("depthMin"), scene length
  double tol_ = 1e-6;        ///< march tolerance above the offset, scene length
  int max_collisions_ = 16;
  int max_iterations_ = 200;
  double rest_speed_ = 0.0;
  bool particle_contacts_ = false;
  double particle_e_ = 1.0;
  std::vector<double> speed_bound_;         ///< per obstacle, this step
  std::vector<std::size_t> timeline_hint_;  ///< per obstacle: its timeline's segment last step
  std::vector<std::size_t> last_segment_;   ///< per obstacle: its segment the step before
  PairContacts pairs_;                      ///< this step's particle-particle contacts
  RestCache rest_;                          ///< particle steps that ended at rest
  DriftRecorder tape_;                      ///< reports drifts while the host records them
  SdfStats stats_;
  /// Particles from which advance() marches them on threads when there are threads: below
  /// it the serial loop is as fast (bench/threads, docs/threads.md).
  static constexpr std::size_t kParallelParticles = 256;
  /// Particles per chunk on threads (any value gives the same bits): each chunk is a task,
  /// so a chunk holds enough marches (whose cost varies with what the ball meets) to
  /// outweigh the taking of a task, and a large state still has many chunks to balance.
  static constexpr std::size_t kChunk = 256;
  /// The first particle with finite mass whose velocity travels beyond kMaxMagnitude in dt,
  /// s.n if none; in fixed chunks on threads if `threads`.
  std::size_t too_fast(const MutableState& s, double dt, bool threads);
  std::vector<std::size_t> first_too_fast_;              ///< per chunk of kParticleChunk, this step
  std::vector<SdfStats> chunk_stats_;                    ///< per chunk, this step
  std::vector<std::vector<pinsim_event>> chunk_events_;  ///< per chunk, this step
  std::vector<std::vector<pinsim_event>> late_events_;   ///< per chunk: particles in hits
  std::vector<SdfStats> late_stats_;                     ///< per chunk: their counters
  std::vector<std::size_t> late_mark_;  ///< per chunk: late_events_ before those kept apart
  std::vector<std::vector<uint32_t>> kept_apart_;  ///< per chunk: particles in later hits
  std::vector<char> marched_early_;  ///< per chunk: its particles in hits marched beside the hits
};

}  // namespace pinsim::sdf
