#include "pair_contacts.hpp"

#include <algorithm>
#include <cmath>
#include <pinsim/parallel.hpp>

namespace pinsim::sdf {

namespace {
/// Hits per chunk of a wave (any value gives the same bits).
constexpr std::size_t kWaveHits = 64;
/// Hits from which a wave runs on threads: below it one thread resolves it faster than
/// threads can be woken.
constexpr std::size_t kParallelWave = 256;
/// Hits from which order_hits sorts by buckets (below: std::sort); hits per task of its
/// buckets' sorts on threads.
constexpr std::size_t kBucketSort = 64;
constexpr std::size_t kSortHits = 2048;
/// Hits between two publications of the resolution's progress (resolved_below()).
constexpr std::size_t kPublish = 64;
/// Hits per task of the islands' resolution (a task ends at the first island boundary past it).
constexpr uint32_t kIslandTask = 256;
}  // namespace

// Pair contacts in four stages:
// 1. find_hits (pair_list.cpp): each particle's box swept over the step (grown by its
//    radius); pairs whose closed boxes overlap are the candidates, those that meet within
//    the step with the velocities at its start are the hits. The candidates come from a
//    list of nearby pairs, those whose enlarged boxes overlap, kept while every swept box
//    lies inside its enlarged box (then any two that overlap are listed).
// 2. order_hits: the hits in order of (tau, i, j) (unique keys: any sort gives this order).
// 3. resolve: in that order, each hit recomputes its time of impact from the current
//    reference states of its two particles and applies the impulse. A hit reads and writes
//    only its two particles' states, so the result is the same for any order of the hits
//    that keeps each particle's hits in their order: one thread takes them in order (and
//    publishes how far it is: resolved_below()); on threads, the islands of the contact
//    graph side by side (resolve_islands), or else waves (a hit's wave is one after the last
//    wave of either particle's earlier hits: a greedy colouring of the contact graph in time
//    order), the hits of a wave share no particle and run at once, waves one after another.
// 4. each particle's velocity changes are a chain through the outcomes of its hits, linked as
//    they are resolved (in order: a particle's hits are); the events in order of (tau, i, j),
//    as one serial loop over the sorted hits gives them: on one thread each as its hit fires
//    (its outcome still in cache), else after the waves or islands in that order.
void PairContacts::schedule(const MutableState& s, double dt, double e, bool threads, EventSink& ev,
                            DriftRecorder* tape) {
  find(s, dt, threads, tape);
  resolve_found(s, dt, e, threads, ev);
}

std::size_t PairContacts::find(const MutableState& s, double dt, bool threads, DriftRecorder* tape,
                               double max_travel) {
  counts_ = Counts{};
  resolved_below_.store(0, std::memory_order_relaxed);
  sim_t_ = s.t;
  tape_ = tape;
  if (tape_ != nullptr) threads = false;  // the tape takes the hits in their order
  // (scan_list marks the particles in hits: in_hit_)
  return find_hits(s, dt, threads, max_travel);
}

void PairContacts::resolve_found(const MutableState& s, double dt, double e, bool threads,
                                 EventSink& ev) {
  if (tape_ != nullptr) threads = false;
  order_hits(threads, dt);
  resolve(s, dt, e, threads, ev);
}

// The keys (tau, i, j) are unique, so any correct sort gives the same order. The hits that
// touch at the start (tau = 0, the scan put them in ordered_) come first, in order of (i, j)
// (sort_touching); then the others (later_): a counting sort by a bucket of tau that never
// decreases with tau (floor(tau B / dt), B = the number of them), then each bucket sorted by
// the full key. The result in hits_.
void PairContacts::order_hits(bool threads, double dt) {
  auto before = [](const Hit& a, const Hit& b) {
    return a.tau < b.tau || (a.tau == b.tau && (a.i < b.i || (a.i == b.i && a.j < b.j)));
  };
  const std::size_t touching = touching_n_, apart = later_n_;
  sort_touching(touching);
  Hit* const out = ordered_.data() + touching;
  if (apart < kBucketSort) {
    std::copy(later_.begin(), later_.begin() + static_cast<std::ptrdiff_t>(apart), out);
    std::sort(out, out + apart, before);
    hits_.swap(ordered_);
    return;
  }
  const std::size_t buckets = apart;
  const double scale = static_cast<double>(apart) / dt;
  auto bucket = [&](double tau) {
    return std::min(apart - 1, static_cast<std::size_t>(tau * scale));
  };
  std::vector<uint32_t>& start = fill_;
  start.assign(buckets + 1, 0);
  for (std::size_t k = 0; k < apart; ++k) ++start[bucket(later_[k].tau) + 1];
  for (std::size_t k = 0; k < buckets; ++k) start[k + 1] += start[k];
  bucket_start_.assign(start.begin(), start.end());
  for (std::size_t k = 0; k < apart; ++k) out[start[bucket(later_[k].tau)]++] = later_[k];
  // each bucket in order: insertion sort for a few hits, else std::sort; on threads, runs of
  // buckets of about kSortHits hits apart (each writes only its own buckets)
  auto sort_buckets = [&](std::size_t k0, std::size_t k1) {
    for (std::size_t k = k0; k < k1; ++k) {
      Hit* b = out + bucket_start_[k];
      Hit* e = out + bucket_start_[k + 1];
      if (e - b > 16) {
        std::sort(b, e, before);
        continue;
      }
      for (Hit* p = b + 1; p < e; ++p)
        for (Hit* q = p; q > b && before(*q, *(q - 1)); --q) std::swap(*q, *(q - 1));
    }
  };
  if (threads && apart >= kParallelWave) {
    const std::size_t parts = chunk_count(apart, kSortHits);
    for_chunks(parts, 1, [&](std::size_t c, std::size_t, std::size_t) {
      // the buckets whose first hit falls in [c kSortHits, (c + 1) kSortHits)
      auto first = [&](std::size_t h) {
        return static_cast<std::size_t>(
            std::lower_bound(bucket_start_.begin(), bucket_start_.end() - 1, h) -
            bucket_start_.begin());
      };
      sort_buckets(first(c * kSortHits), c + 1 == parts ? buckets : first((c + 1) * kSortHits));
    });
  } else {
    sort_buckets(0, buckets);
  }
  hits_.swap(ordered_);
}

// The first `count` hits of ordered_ (tau = 0: the hits that touch at the start) in order of
// (i, j). The scan finds them in that order from the list (its runs are in increasing order)
// and appends those of the moved particles' pairs: from the first hit out of order on (those,
// or a pair apart whose root rounded to 0) they are sorted and merged in.
void PairContacts::sort_touching(std::size_t count) {
  Hit* b = ordered_.data();
  Hit* e = b + count;
  auto by_pair = [](const Hit& p, const Hit& q) { return p.i < q.i || (p.i == q.i && p.j < q.j); };
  Hit* mid = std::is_sorted_until(b, e, by_pair);
  if (mid == e) return;
  std::sort(mid, e, by_pair);
  touching_.resize(static_cast<std::size_t>(e - b));
  std::merge(b, mid, mid, e, touching_.begin(), by_pair);
  std::copy(touching_.begin(), touching_.end(), b);
}

// The time of impact of two discs in linear motion, |dx + dv tau| = r_i + r_j:
// a tau^2 + 2 b tau + c = 0 with a = dv.dv, b = dx.dv, c = dx.dx - (r_i + r_j)^2, the first
// root tau = (-b - sqrt(b^2 - a c)) / a written as c / (-b + sqrt(b^2 - a c)) (no
// cancellation); already touching (c <= 0) and approaching: tau0 (toi_refs).

// The impulse J = -(1 + e) vn / (w_i + w_j) along the normal n from j to i at the time of
// impact (w: inverse masses, 0 for pinned particles), as velocity changes J w_i n and
// -J w_j n; the reference states move to the contact.
bool PairContacts::resolve_hit(std::size_t h, double dt, double e) {
  const uint32_t i = hits_[h].i, j = hits_[h].j;
  Outcome& out = outcome_[h];
  out.fired = false;
  Start &P = start_[i], &Q = start_[j];
  Ref ri{Vec2(P.x, P.y), Vec2(P.vx, P.vy), ref_t_[i], P.r, P.w};
  Ref rj{Vec2(Q.x, Q.y), Vec2(Q.vx, Q.vy), ref_t_[j], Q.r, Q.w};
  double tau = 0.0;
  if (!toi_refs(ri, rj, ri.r + rj.r, std::max(ri.tr, rj.tr), dt, tau)) return false;
  const Vec2 pi = ri.xr + ri.vc * (tau - ri.tr), pj = rj.xr + rj.vc * (tau - rj.tr);
  const Vec2 dx = pi - pj;
  const double l = dx.norm();
  const Vec2 nrm = l > 0.0 ? Vec2(dx / l) : Vec2(0.0, 1.0);
  const double vn = (ri.vc - rj.vc).dot(nrm);
  if (vn >= 0.0) return false;
  const double wi = ri.w, wj = rj.w;
  const double jn = -(1.0 + e) * vn / (wi + wj);
  const double ai = jn * wi, aj = -jn * wj;  // dv_i = ai n, dv_j = aj n
  if (tape_ != nullptr)
    tape_->pair(i, j, tau, ri.xr, ri.vc, ri.tr, rj.xr, rj.vc, rj.tr, ri.r + rj.r, wi, wj, e);
  ri.vc += ai * nrm;
  rj.vc += aj * nrm;
  P.x = pi.x();
  P.y = pi.y();
  P.vx = ri.vc.x();
  P.vy = ri.vc.y();
  Q.x = pj.x();
  Q.y = pj.y();
  Q.vx = rj.vc.x();
  Q.vy = rj.vc.y();
  ref_t_[i] = ref_t_[j] = tau;
  out = {tau, ai, aj, nrm, pj + rj.r * nrm, vn, (ri.vc - rj.vc).dot(nrm), true};
  if (wi > 0.0) link_change(i, 2 * h);
  if (wj > 0.0) link_change(j, 2 * h + 1);
  return true;
}

void PairContacts::resolve(const MutableState& s, double dt, double e, bool threads,
                           EventSink& ev) {
  const std::size_t hits = hits_.size();
  outcome_.resize(hits);
  next_change_.resize(2 * hits);
  first_change_.assign(s.n, kNoLink);
  last_change_.assign(s.n, kNoLink);
  // (start_ and ref_t_: the reference states of the particles in hits, from find())
  if (!threads || hits < kParallelWave) {
    // one thread: the order of the hits is a schedule. Before hit h, all hits before it are
    // resolved: while they touch at the start they are in order of (i, j), so every hit of a
    // particle below hits_[h].i that touches at the start is among them (published every
    // kPublish hits); past them, every such hit of every particle is.
    const std::size_t touching = touching_n_;
    for (std::size_t h = 0; h < hits; ++h) {
      if (h % kPublish == 0)
        resolved_below_.store(h < touching ? hits_[h].i : s.n, std::memory_order_release);
      if (resolve_hit(h, dt, e)) {
        ++counts_.impulses;
        emit_event(h, ev);
      }
    }
    resolved_below_.store(kAllResolved, std::memory_order_release);
  } else {
    if (!resolve_islands(s, dt, e)) resolve_waves(s.n, dt, e);
    // (every change final: the marching side need not wait for the events)
    resolved_below_.store(kAllResolved, std::memory_order_release);
    for (std::size_t h = 0; h < hits; ++h)
      if (outcome_[h].fired) {
        ++counts_.impulses;
        emit_event(h, ev);
      }
  }
}

// The hits in waves (assign_waves): those of a wave share no particle and run at once, on
// threads when there are enough of them.
void PairContacts::resolve_waves(std::size_t n, double dt, double e) {
  const std::size_t hits = hits_.size();
  const uint32_t levels = assign_waves(n);
  level_start_.assign(static_cast<std::size_t>(levels) + 1, 0);
  for (std::size_t h = 0; h < hits; ++h) ++level_start_[level_of_[h] + 1];
  for (std::size_t l = 0; l < levels; ++l) level_start_[l + 1] += level_start_[l];
  by_level_.resize(hits);
  {
    std::vector<uint32_t>& fill = fill_;
    fill.assign(level_start_.begin(), level_start_.end() - 1);
    for (std::size_t h = 0; h < hits; ++h)
      by_level_[fill[level_of_[h]]++] = static_cast<uint32_t>(h);
  }
  for (std::size_t l = 0; l < levels; ++l) {
    const std::size_t b = level_start_[l], count = level_start_[l + 1] - b;
    auto wave = [&](std::size_t, std::size_t k0, std::size_t k1) {
      for (std::size_t k = k0; k < k1; ++k) resolve_hit(by_level_[b + k], dt, e);
    };
    if (count >= kParallelWave)
      for_chunks(count, kWaveHits, wave);
    else
      wave(0, 0, count);
  }
}

// Waves: a hit goes one wave after the last of its particles' earlier hits.
uint32_t PairContacts::assign_waves(std::size_t n) {
  const std::size_t hits = hits_.size();
  last_level_.assign(n, 0);
  level_of_.resize(hits);
  uint32_t levels = 0;
  for (std::size_t h = 0; h < hits; ++h) {
    const uint32_t i = hits_[h].i, j = hits_[h].j;
    const uint32_t lv = std::max(last_level_[i], last_level_[j]);
    last_level_[i] = last_level_[j] = lv + 1;
    level_of_[h] = lv;
    levels = std::max(levels, lv + 1);
  }
  counts_.levels = levels;
  return levels;
}

// Islands: the connected parts of the contact graph (particles joined by hits), by union-find
// with the smallest particle index as each part's root. Hits of different islands share no
// particle, so each island's hits run in their order on one thread, islands side by side:
// the hits in order of their island's root (a stable counting sort: in order within each),
// cut into tasks at island boundaries once a task holds kIslandTask hits (fixed by the hits,
// not by the threads). Used when no island holds more than half of the hits (else the waves
// share the work better); false if not used.
bool PairContacts::resolve_islands(const MutableState& s, double dt, double e) {
  const std::size_t n = s.n, hits = hits_.size();
  std::vector<uint32_t>& parent = parent_;
  parent.resize(n);
  for (std::size_t i = 0; i < n; ++i) parent[i] = static_cast<uint32_t>(i);
  auto find = [&](uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  for (const Hit& h : hits_) {
    const uint32_t a = find(h.i), b = find(h.j);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
  std::vector<uint32_t>& start = fill_;
  start.assign(n + 1, 0);
  root_of_.resize(hits);
  for (std::size_t h = 0; h < hits; ++h) {
    root_of_[h] = find(hits_[h].i);
    ++start[root_of_[h] + 1];
  }
  uint32_t largest = 0;
  for (std::size_t i = 0; i < n; ++i) {
    largest = std::max(largest, start[i + 1]);
    start[i + 1] += start[i];
  }
  counts_.largest_island = largest;
  if (2 * static_cast<std::size_t>(largest) > hits) return false;
  by_level_.resize(hits);
  // tasks: island boundaries after every kIslandTask hits or more
  task_start_.assign(1, 0);
  for (std::size_t i = 0; i < n; ++i)
    if (start[i + 1] - task_start_.back() >= kIslandTask) task_start_.push_back(start[i + 1]);
  if (task_start_.back() != hits) task_start_.push_back(static_cast<uint32_t>(hits));
  for (std::size_t h = 0; h < hits; ++h) by_level_[start[root_of_[h]]++] = static_cast<uint32_t>(h);
  for_chunks(task_start_.size() - 1, 1, [&](std::size_t t, std::size_t, std::size_t) {
    for (uint32_t k = task_start_[t]; k < task_start_[t + 1]; ++k) resolve_hit(by_level_[k], dt, e);
  });
  return true;
}

void PairContacts::emit_event(std::size_t h, EventSink& ev) const {
  const Outcome& o = outcome_[h];
  pinsim_event event{};
  event.t = sim_t_ + o.tau;
  event.particle = hits_[h].i;
  event.obstacle = -1;
  event.other = hits_[h].j;
  event.point[0] = o.point.x();
  event.point[1] = o.point.y();
  event.normal[0] = o.nrm.x();
  event.normal[1] = o.nrm.y();
  event.vn_before = o.vn;
  event.vn_after = o.vn_after;
  ev.emit(event);
}

}  // namespace pinsim::sdf
