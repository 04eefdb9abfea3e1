// PairContacts: the sdf backend's particle-particle contacts within one step, found from a
// list of nearby pairs (a uniform grid over enlarged swept boxes, kept over the steps while
// every particle's swept box stays inside its enlarged one), resolved in order of their time
// of impact and handed to the obstacle march as velocity changes (README: Particle-particle
// contacts).
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <pinsim/plugin.hpp>
#include <utility>
#include <vector>

#include "drift_recorder.hpp"
#include "pair_look.hpp"

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
    std::size_t levels = 0;          ///< waves of hits sharing no particle (when waves ran)
    std::size_t largest_island = 0;  ///< hits of the largest island (when islands were tried)
    std::size_t listed = 0;          ///< pairs in the list of nearby pairs
    bool rebuilt = false;            ///< whether this step built that list anew
    std::size_t moved = 0;           ///< else, particles given a new box in it
  };

  /// The step's pair contacts of s over [s.t, s.t + dt] with restitution e: every particle's
  /// velocity changes (changes(i)), and one event per impulse emitted into ev in order of
  /// (time, i, j). `threads`: the stages may run on oneTBB's threads; the results are the
  /// same bits either way and for any thread count. `tape` (null: none) gets every hit as it
  /// is resolved, in the order of the hits (then threads must be false).
  void schedule(const MutableState& s, double dt, double e, bool threads, EventSink& ev,
                DriftRecorder* tape = nullptr);
  /// schedule() in two parts, for a caller with other work between them: find() the
  /// step's hits (then in_hit(i) tells whether particle i may change in this step), then
  /// resolve_found() them (then changes(i) holds) and emit their events into ev in order
  /// (from the calling thread; on one thread each as its hit fires).
  /// find() first checks every particle with finite mass: the first (in index order) whose
  /// velocity travels beyond `max_travel` along an axis in dt (or is NaN) is returned and
  /// no hit is found (counts() reads 0); else s.n (always with max_travel = HUGE_VAL: no
  /// check).
  std::size_t find(const MutableState& s, double dt, bool threads, DriftRecorder* tape = nullptr,
                   double max_travel = HUGE_VAL);
  void resolve_found(const MutableState& s, double dt, double e, bool threads, EventSink& ev);
  /// Whether particle i is in one of the hits find() found.
  bool in_hit(std::size_t i) const { return in_hit_[i] != 0; }
  /// Whether particle i is in a hit that does not touch at the start (tau > 0).
  bool late(std::size_t i) const { return (in_hit_[i] & kLate) != 0; }
  /// While resolve_found() runs on another thread: every particle below the value returned
  /// whose hits all touch at the start (not late()) has its changes(i) final; every particle
  /// has at kAllResolved. Reset by find(); read with acquire, so what the resolution wrote
  /// for those particles is visible to the reader.
  std::size_t resolved_below() const { return resolved_below_.load(std::memory_order_acquire); }
  static constexpr std::size_t kAllResolved = ~std::size_t{0};
  /// No pair contacts in this step for particles 0..n-1 (changes(i) empty).
  void clear(std::size_t n) { first_change_.assign(n, kNoLink); }
  class ChangeRange;
  /// Particle i's velocity changes in this step, in order of time.
  ChangeRange changes(std::size_t i) const;
  /// Whether particle i has a velocity change in this step.
  bool changed(std::size_t i) const { return first_change_[i] != kNoLink; }
  const Counts& counts() const { return counts_; }

 private:
  /// A box (particle i's swept or enlarged box).
  using Box = SweptBox;
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
  using Start = PairStart;
  /// Where a particle is along its straight path: at xr at time tr, velocity vc; its
  /// radius and inverse mass (resolve_hit's copy of start_ and ref_t_).
  struct Ref {
    Vec2 xr, vc;
    double tr, r, w;
  };
  /// What resolving one hit gave: whether it fired; its impulses (velocity changes ai n and
  /// aj n) and its event's figures.
  struct Outcome {
    double tau, ai, aj;
    Vec2 nrm, point;  ///< normal from j to i, contact point
    double vn, vn_after;
    bool fired;
  };

  static constexpr std::size_t kNoList = ~std::size_t{0};
  /// in_hit_ flags: in a hit that touches at the start, in one that does not.
  static constexpr char kTouching = 1, kLate = 2;
  /// A particle's velocity changes are a chain through the outcomes of its hits that fired:
  /// link 2 h is hit h's change of its particle i, 2 h + 1 that of j (kNoLink: none).
  static constexpr std::size_t kNoLink = ~std::size_t{0};
  /// Appends link k (a change at hit h) to particle p's chain.
  void link_change(uint32_t p, std::size_t k) {
    next_change_[k] = kNoLink;
    if (last_change_[p] == kNoLink)
      first_change_[p] = k;
    else
      next_change_[last_change_[p]] = k;
    last_change_[p] = k;
  }

  /// The hits, or the first particle too fast (find()).
  std::size_t find_hits(const MutableState& s, double dt, bool threads, double max_travel);
  /// The start states of the step and the particles whose swept box is not inside their
  /// box of the list (leavers_); whether a list exists for these particles. too_fast_: the
  /// first particle too fast (find()), s.n if none.
  bool sweep(const MutableState& s, double dt, bool threads, double max_travel);
  /// The list of nearby pairs anew: enlarged boxes, a grid over them, pairs by lower index.
  void build_list(const MutableState& s, double dt, bool threads);
  /// Particle i's enlarged box (NaN: no finite swept box, left out of the list).
  Box enlarged(std::size_t i, double dt) const;
  /// The leavers with new enlarged boxes in the kept list: their listed pairs retired, their
  /// pairs with the new boxes found in the build's grid and among the particles moved before.
  void move_in_list(double dt);
  /// f(j) for each particle j whose box in the build's grid may overlap box b.
  template <class F>
  void in_grid(const Box& b, F&& f) const;
  /// The hits among the listed pairs: swept boxes that overlap, meeting within the step.
  void scan_list(double dt, bool threads);
  /// The hits among k pairs (ni[m], nj[m]) into out, those touching at the start first
  /// (pair_list.cpp; ni and nj are used as scratch).
  std::size_t times_of_impact(uint32_t* ni, uint32_t* nj, std::size_t k, double dt,
                              std::vector<Hit>& out) const;
  void order_hits(bool threads, double dt);
  void sort_touching(std::size_t count);
  void resolve(const MutableState& s, double dt, double e, bool threads, EventSink& ev);
  /// The event of hit h (fired).
  void emit_event(std::size_t h, EventSink& ev) const;
  void resolve_waves(std::size_t n, double dt, double e);
  /// Each hit's wave (for the waves on threads); the number of waves.
  uint32_t assign_waves(std::size_t n);
  bool resolve_islands(const MutableState& s, double dt, double e);
  /// Time of impact after tau0 of two particles moving linearly from their reference states,
  /// the sum of their radii rr.
  static inline bool toi_refs(const Ref& ri, const Ref& rj, double rr, double tau0, double dt,
                              double& tau);
  /// Resolves hit h from the reference states of its particles (updating them and linking
  /// their changes); whether it fired.
  bool resolve_hit(std::size_t h, double dt, double e);

  /// per particle: its start state (sweep()); from resolve() on, for a particle in a hit, its
  /// reference state instead (position and velocity moved on to its last contact, at time
  /// ref_t_) until the next sweep()
  std::vector<Start> start_;
  std::vector<double> ref_t_;
  std::vector<Box> fat_;              ///< per particle: its box in the list (NaN: none)
  std::vector<uint32_t> list_start_;  ///< per particle (+1): first entry in list_
  std::vector<std::pair<uint32_t, uint32_t>> list_;   ///< listed pairs (i < j), by i
  std::size_t listed_n_ = kNoList;                    ///< particles of the list (kNoList: no list)
  std::vector<std::vector<uint32_t>> chunk_leavers_;  ///< per particle chunk: boxes outside
  std::vector<std::size_t> chunk_too_fast_;           ///< per particle chunk: first too fast
  std::size_t too_fast_ = 0;                          ///< sweep()'s first too fast
  std::vector<uint32_t> leavers_;  ///< this step's particles outside their fat boxes
  std::vector<std::pair<uint32_t, uint32_t>> extra_;  ///< pairs (i < j) of moved particles
  std::vector<char> moved_;          ///< per particle: given a new box since the build
  std::vector<uint32_t> moved_ids_;  ///< those particles
  std::vector<char> leaving_;        ///< per particle: a leaver in this step (move_in_list)
  double grid_x0_ = 0.0, grid_y0_ = 0.0, grid_h_ = 0.0;  ///< the build's grid: origin, cell
  std::size_t grid_nx_ = 0, grid_ny_ = 0;                ///< and cells (0: none)
  std::size_t dead_ = 0;        ///< list_ entries retired (a particle's own index)
  std::size_t steps_kept_ = 0;  ///< steps since the list was built
  /// per chunk of the build's scan and part of the particles: its pairs
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> chunk_pairs_;
  std::vector<uint32_t> part_start_;  ///< per part: its first entry in list_
  std::vector<uint32_t> cell_of_;     ///< per particle: its fat box's home cell (~0u: none)
  std::vector<uint32_t> cell_start_;  ///< per cell: first entry in sorted_
  std::vector<Sorted> sorted_;        ///< fat boxes by cell, in increasing index per cell
  std::vector<std::vector<uint32_t>> chunk_near_;  ///< per scan chunk: overlapping entries
  std::vector<std::vector<Hit>> chunk_hits_;
  std::vector<std::size_t> chunk_candidates_;
  std::vector<Hit> hits_;     ///< in order of (tau, i, j)
  std::vector<char> in_hit_;  ///< per particle: kTouching | kLate, the hits it is in
  std::atomic<std::size_t> resolved_below_{0};  ///< see resolved_below()
  std::vector<Hit> ordered_;  ///< the scan's touching hits (touching_n_), then order_hits()'s
  std::vector<Hit> later_;    ///< the scan's other hits (later_n_)
  std::size_t touching_n_ = 0, later_n_ = 0;
  std::vector<std::size_t> chunk_touching_;  ///< per scan chunk: its touching hits (first)
  std::vector<uint32_t> bucket_start_;       ///< per bucket of order_hits(): first hit
  std::vector<Hit> touching_;                ///< sort_touching()'s merged hits
  std::vector<Outcome> outcome_;             ///< per hit
  std::vector<uint32_t> level_of_;           ///< per hit: its wave
  std::vector<uint32_t> last_level_;         ///< per particle: wave of its last hit so far
  std::vector<uint32_t> level_start_;        ///< per wave: first entry in by_level_
  std::vector<uint32_t> by_level_;           ///< hits by wave or island, in order within each
  std::vector<uint32_t> parent_;             ///< per particle: union-find parent
  std::vector<uint32_t> root_of_;            ///< per hit: its island's root particle
  std::vector<uint32_t> task_start_;         ///< per island task: first entry in by_level_
  std::vector<std::size_t> first_change_;    ///< per particle: first link of its changes
  std::vector<std::size_t> last_change_;     ///< per particle: last link so far (resolve())
  std::vector<std::size_t> next_change_;     ///< per link: the next of its particle
  std::vector<uint32_t> fill_;               ///< counting sorts' next free entries
  Counts counts_;
  double sim_t_ = 0.0;
  DriftRecorder* tape_ = nullptr;  ///< this schedule's drift recorder, if any
};

/// Particle i's changes: an input range over its chain of links.
class PairContacts::ChangeRange {
 public:
  class iterator {
   public:
    using iterator_category = std::input_iterator_tag;
    using value_type = Change;
    using difference_type = std::ptrdiff_t;
    using pointer = void;
    using reference = Change;
    iterator(const PairContacts* pc, std::size_t k) : pc_(pc), k_(k) {}
    Change operator*() const {
      const Outcome& o = pc_->outcome_[k_ / 2];
      return {o.tau, ((k_ & 1) != 0 ? o.aj : o.ai) * o.nrm};
    }
    iterator& operator++() {
      k_ = pc_->next_change_[k_];
      return *this;
    }
    iterator operator++(int) {
      iterator before = *this;
      ++*this;
      return before;
    }
    bool operator==(const iterator& o) const { return k_ == o.k_; }

   private:
    const PairContacts* pc_;
    std::size_t k_;
  };
  ChangeRange(const PairContacts* pc, std::size_t first) : pc_(pc), first_(first) {}
  iterator begin() const { return {pc_, first_}; }
  iterator end() const { return {pc_, kNoLink}; }
  bool empty() const { return first_ == kNoLink; }

 private:
  const PairContacts* pc_;
  std::size_t first_;
};

inline PairContacts::ChangeRange PairContacts::changes(std::size_t i) const {
  return {this, first_change_[i]};
}

// (pair_contacts.cpp: the formula)
inline bool PairContacts::toi_refs(const Ref& ri, const Ref& rj, double rr, double tau0, double dt,
                                   double& tau) {
  const Vec2 pi = ri.xr + ri.vc * (tau0 - ri.tr), pj = rj.xr + rj.vc * (tau0 - rj.tr);
  const Vec2 dx = pi - pj, dv = ri.vc - rj.vc;
  const double a = dv.squaredNorm(), b = dx.dot(dv), c = dx.squaredNorm() - rr * rr;
  if (b >= 0.0) return false;  // not approaching
  if (c <= 0.0) {
    tau = tau0;
    return true;
  }
  const double disc = b * b - a * c;
  if (disc < 0.0) return false;
  tau = tau0 + c / (-b + std::sqrt(disc));
  return tau <= dt;
}

}  // namespace pinsim::sdf
