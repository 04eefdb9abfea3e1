// PairContacts: the sdf backend's particle-particle contacts within one step, found by a
// uniform grid over the boxes the particles sweep, resolved in order of their time of impact
// and handed to the obstacle march as velocity changes (README: Particle-particle contacts).
#pragma once

#include <cstddef>
#include <cstdint>
#include <pinsim/plugin.hpp>
#include <span>
#include <vector>

#include "drift_recorder.hpp"

namespace pinsim::sdf {

class PairContacts {
 public:
  /// A velocity change of one particle at a pair contact.
  struct Change {
    double tau;  ///< time into the step, s
    Vec2 dv;     ///< velocity change
  };
  /// What the last schedule() found and did (for tests and benchmarks).
  struct Counts {
    std::size_t candidates = 0;      ///< pairs whose swept boxes overlap
    std::size_t hits = 0;            ///< of them, pairs that meet within the step at first sight
    std::size_t impulses = 0;        ///< impulses applied (events emitted)
    std::size_t levels = 0;          ///< waves of hits sharing no particle (see schedule())
    std::size_t largest_island = 0;  ///< hits of the largest island (on threads only)
  };

  /// The step's pair contacts of s over [s.t, s.t + dt] with restitution e: every particle's
  /// velocity changes (changes(i)), and one event per impulse emitted into ev in order of
  /// (time, i, j). `threads`: the stages may run on oneTBB's threads; the results are the
  /// same bits either way and for any thread count. `tape` (null: none) gets every hit as it
  /// is resolved, in the order of the hits (then threads must be false).
  void schedule(const MutableState& s, double dt, double e, bool threads, EventSink& ev,
                DriftRecorder* tape = nullptr);
  /// No pair contacts in this step for particles 0..n-1 (changes(i) empty).
  void clear(std::size_t n) {
    change_start_.assign(n + 1, 0);
    changes_.clear();
  }
  /// Particle i's velocity changes in this step, in order of time.
  std::span<const Change> changes(std::size_t i) const {
    return {changes_.data() + change_start_[i], changes_.data() + change_start_[i + 1]};
  }
  /// Whether particle i has a velocity change in this step.
  bool changed(std::size_t i) const { return change_start_[i + 1] != change_start_[i]; }
  const Counts& counts() const { return counts_; }

 private:
  /// The box particle i sweeps over the step, grown by its radius.
  struct Box {
    double x0, x1, y0, y1;
  };
  /// A box in the grid's order, with its particle and the entries to compare it with:
  /// [this + 1, up) and [b0, b1).
  struct Sorted {
    Box box;
    uint32_t id, up, b0, b1;
  };
  /// A pair (i < j) that meets at tau (time into the step) with the velocities at the start.
  struct Hit {
    double tau;
    uint32_t i, j;
  };
  /// Where a particle is along its straight path: at xr at time tr, velocity vc.
  struct Ref {
    Vec2 xr, vc;
    double tr;
  };
  /// A particle's start state in the grid's order: reference state, radius, inverse mass.
  struct Body {
    Ref ref;
    double r, w;
  };
  /// What resolving one hit gave: whether it fired, its impulses and its event.
  struct Outcome {
    double tau;
    Vec2 dvi, dvj;
    pinsim_event event;
    bool fired;
  };

  void find_hits(const MutableState& s, double dt, bool threads);
  void order_hits(std::size_t n, bool threads, double dt);
  void sort_touching(std::size_t n);
  void resolve(const MutableState& s, double dt, double e, bool threads);
  bool resolve_islands(const MutableState& s, double dt, double e);
  void collect(const MutableState& s, EventSink& ev);
  /// Time of impact after tau0 of i and j moving linearly from their reference states.
  bool toi(const MutableState& s, uint32_t i, uint32_t j, double tau0, double dt,
           double& tau) const;
  /// The same from the two reference states and the sum of the radii rr.
  static inline bool toi_refs(const Ref& ri, const Ref& rj, double rr, double tau0, double dt,
                              double& tau);
  /// Resolves hit h from the reference states of its particles (updating them).
  void resolve_hit(const MutableState& s, std::size_t h, double dt, double e);

  std::vector<Box> boxes_;
  std::vector<Ref> ref_;
  std::vector<uint32_t> cell_of_;     ///< per particle: its box's home cell (~0u: none)
  std::vector<uint32_t> cell_start_;  ///< per cell: first entry in by_cell_
  std::vector<Sorted> sorted_;        ///< boxes by cell, in increasing index per cell
  std::vector<Body> sorted_body_;     ///< the same particles' start states
  std::vector<std::vector<uint32_t>> chunk_near_;  ///< per scan chunk: overlapping entries
  std::vector<std::vector<Hit>> chunk_hits_;
  std::vector<std::size_t> chunk_candidates_;
  std::vector<Hit> hits_;                  ///< in order of (tau, i, j)
  std::vector<Hit> ordered_;               ///< order_hits()'s buckets
  std::vector<uint32_t> bucket_start_;     ///< per bucket of order_hits(): first hit
  std::vector<Hit> touching_;              ///< sort_touching()'s hits by i
  std::vector<uint32_t> touch_start_;      ///< sort_touching()'s runs of one i
  std::vector<Outcome> outcome_;           ///< per hit
  std::vector<uint32_t> level_of_;         ///< per hit: its wave
  std::vector<uint32_t> last_level_;       ///< per particle: wave of its last hit so far
  std::vector<uint32_t> level_start_;      ///< per wave: first entry in by_level_
  std::vector<uint32_t> by_level_;         ///< hits by wave or island, in order within each
  std::vector<uint32_t> parent_;           ///< per particle: union-find parent
  std::vector<uint32_t> root_of_;          ///< per hit: its island's root particle
  std::vector<uint32_t> task_start_;       ///< per island task: first entry in by_level_
  std::vector<std::size_t> change_start_;  ///< per particle (+1): first entry in changes_
  std::vector<Change> changes_;
  std::vector<uint32_t> fill_;             ///< counting sorts' next free entries
  std::vector<std::size_t> fill_changes_;  ///< collect()'s next free entries
  Counts counts_;
  double sim_t_ = 0.0;
  DriftRecorder* tape_ = nullptr;  ///< this schedule's drift recorder, if any
};

}  // namespace pinsim::sdf
