#include "pair_contacts.hpp"

#include <algorithm>
#include <cmath>
#include <pinsim/parallel.hpp>

namespace pinsim::sdf {

namespace {
/// Particles per chunk of the per-particle loops; entries per chunk of the grid's scan; hits
/// per chunk of a wave (any value gives the same bits).
constexpr std::size_t kParticles = 1024;
constexpr std::size_t kEntries = 512;
constexpr std::size_t kWaveHits = 64;
/// Hits from which a wave runs on threads: below it one thread resolves it faster than
/// threads can be woken.
constexpr std::size_t kParallelWave = 256;
constexpr uint32_t kNoCell = ~0u;
/// Hits from which order_hits sorts by buckets (below: std::sort); hits per task of its
/// buckets' sorts on threads.
constexpr std::size_t kBucketSort = 64;
constexpr std::size_t kSortHits = 2048;
/// Hits per task of the islands' resolution (a task ends at the first island boundary past it).
constexpr uint32_t kIslandTask = 256;
}  // namespace

// Pair contacts in four stages:
// 1. find_hits: each particle's box swept over the step (grown by its radius) goes into a
//    uniform grid whose cells are as large as the largest box, so two boxes that overlap
//    have home cells (the cell of the box's lower corner) at most one apart; each cell is
//    compared with itself and four of its neighbours, so each pair is seen once. Pairs
//    whose closed boxes overlap are the candidates; those that meet within the step with the
//    velocities at its start are the hits.
// 2. order_hits: the hits in order of (tau, i, j) (unique keys: any sort gives this order).
// 3. resolve: in that order, each hit recomputes its time of impact from the current
//    reference states of its two particles and applies the impulse. A hit reads and writes
//    only its two particles' states, so the result is the same for any order of the hits
//    that keeps each particle's hits in their order: the hits are grouped in waves (a hit's
//    wave is one after the last wave of either particle's earlier hits: a greedy colouring
//    of the contact graph in time order), the hits of a wave share no particle and run at
//    once, waves one after another.
// 4. collect: each particle's velocity changes in order, and the events in order of
//    (tau, i, j), as one serial loop over the sorted hits would give.
void PairContacts::schedule(const MutableState& s, double dt, double e, bool threads, EventSink& ev,
                            DriftRecorder* tape) {
  counts_ = Counts{};
  sim_t_ = s.t;
  tape_ = tape;
  if (tape_ != nullptr) threads = false;  // the tape takes the hits in their order
  find_hits(s, dt, threads);
  order_hits(s.n, threads, dt);
  resolve(s, dt, e, threads);
  collect(s, ev);
}

void PairContacts::find_hits(const MutableState& s, double dt, bool threads) {
  const std::size_t n = s.n;
  boxes_.resize(n);
  ref_.resize(n);
  cell_of_.resize(n);
  // Boxes and reference states; bounds and the largest extent of the finite boxes (min and
  // max are exact, so per-chunk partials combine to the same values in any order).
  struct Extent {
    double x0 = HUGE_VAL, y0 = HUGE_VAL, x1 = -HUGE_VAL, y1 = -HUGE_VAL, size = 0.0;
  };
  const std::size_t pchunks = chunk_count(n, kParticles);
  std::vector<Extent> part(pchunks);
  auto boxes = [&](std::size_t c, std::size_t b, std::size_t end) {
    Extent ex;
    for (std::size_t i = b; i < end; ++i) {
      const bool moves = s.inv_mass[i] > 0.0;
      const Vec2 a = s.x.col(i), p = a + (moves ? Vec2(dt * s.v.col(i)) : Vec2::Zero());
      const double r = s.radius[i];
      const Box bx{std::min(a.x(), p.x()) - r, std::max(a.x(), p.x()) + r,
                   std::min(a.y(), p.y()) - r, std::max(a.y(), p.y()) + r};
      boxes_[i] = bx;
      ref_[i] = {a, moves ? Vec2(s.v.col(i)) : Vec2::Zero(), 0.0};
      const bool finite = std::isfinite(bx.x0) && std::isfinite(bx.x1) && std::isfinite(bx.y0) &&
                          std::isfinite(bx.y1);
      cell_of_[i] = finite ? 0u : kNoCell;
      if (!finite) continue;
      ex.x0 = std::min(ex.x0, bx.x0);
      ex.y0 = std::min(ex.y0, bx.y0);
      ex.x1 = std::max(ex.x1, bx.x1);
      ex.y1 = std::max(ex.y1, bx.y1);
      ex.size = std::max({ex.size, bx.x1 - bx.x0, bx.y1 - bx.y0});
    }
    part[c] = ex;
  };
  if (threads)
    for_chunks(n, kParticles, boxes, Schedule::Even);
  else
    for (std::size_t c = 0; c < pchunks; ++c)
      boxes(c, c * kParticles, std::min(n, (c + 1) * kParticles));
  Extent all;
  for (const Extent& ex : part) {
    all.x0 = std::min(all.x0, ex.x0);
    all.y0 = std::min(all.y0, ex.y0);
    all.x1 = std::max(all.x1, ex.x1);
    all.y1 = std::max(all.y1, ex.y1);
    all.size = std::max(all.size, ex.size);
  }
  hits_.clear();
  if (!(all.x0 <= all.x1)) return;  // no finite box
  // Cells a little larger than the largest box (so rounding in the cell index cannot put
  // two overlapping boxes two cells apart), and at most about 4 n of them.
  const double w = all.x1 - all.x0, hgt = all.y1 - all.y0;
  double h = all.size * (1.0 + 1e-6);
  if (!(h > 0.0)) h = std::max({w, hgt, 1e-300});
  const double limit = 4.0 * static_cast<double>(n) + 16.0;
  while ((std::floor(w / h) + 1.0) * (std::floor(hgt / h) + 1.0) > limit) h *= 1.5;
  const auto nx = static_cast<std::size_t>(std::floor(w / h)) + 1;
  const auto ny = static_cast<std::size_t>(std::floor(hgt / h)) + 1;
  const std::size_t cells = nx * ny;
  // Counting sort of the boxes by home cell, cells column by column (cell cx ny + cy), in
  // increasing particle index within a cell: a cell and the one above it, and the three
  // cells of the next column beside them, are each one contiguous run. Each entry carries
  // its particle's box and, apart, its start state (the scan reads them in order).
  cell_start_.assign(cells + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (cell_of_[i] == kNoCell) continue;
    const auto cx = std::min(nx - 1, static_cast<std::size_t>((boxes_[i].x0 - all.x0) / h));
    const auto cy = std::min(ny - 1, static_cast<std::size_t>((boxes_[i].y0 - all.y0) / h));
    cell_of_[i] = static_cast<uint32_t>(cx * ny + cy);
    ++cell_start_[cell_of_[i] + 1];
  }
  for (std::size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
  const std::size_t entries = cell_start_[cells];
  sorted_.resize(entries);
  sorted_body_.resize(entries);
  {
    std::vector<uint32_t>& fill = fill_;
    fill.assign(cell_start_.begin(), cell_start_.end() - 1);
    for (std::size_t i = 0; i < n; ++i) {
      const uint32_t c = cell_of_[i];
      if (c == kNoCell) continue;
      const uint32_t k = fill[c]++;
      // the runs of this cell's neighbours: up to the end of the cell above, and the cells
      // of the next column from the row below to the row above
      const std::size_t cx = c / ny, cy = c % ny, right = c + ny;
      const uint32_t up = cell_start_[cy + 1 < ny ? c + 2 : c + 1];
      const bool next = cx + 1 < nx;
      const uint32_t b0 = next ? cell_start_[cy > 0 ? right - 1 : right] : 0;
      const uint32_t b1 = next ? cell_start_[cy + 1 < ny ? right + 2 : right + 1] : 0;
      sorted_[k] = {boxes_[i], static_cast<uint32_t>(i), up, b0, b1};
      sorted_body_[k] = {ref_[i], s.radius[i], s.inv_mass[i]};
    }
  }
  // Each entry against the later entries of its cell and the cell above, and the cells
  // (+1, -1), (+1, 0), (+1, +1): each pair of cells at most one apart is seen once. The boxes
  // that overlap are first gathered without branches, then tested.
  const std::size_t echunks = chunk_count(entries, kEntries);
  chunk_hits_.resize(echunks);
  chunk_candidates_.assign(echunks, 0);
  chunk_near_.resize(echunks);
  auto scan = [&](std::size_t c, std::size_t b, std::size_t end) {
    std::vector<Hit>& out = chunk_hits_[c];
    std::vector<uint32_t>& near = chunk_near_[c];
    out.clear();
    std::size_t candidates = 0;
    const Sorted* box = sorted_.data();
    const Body* body = sorted_body_.data();
    for (std::size_t a = b; a < end; ++a) {
      const Box A = box[a].box;
      const uint32_t up = box[a].up, b0 = box[a].b0, b1 = box[a].b1;
      const std::size_t need = static_cast<std::size_t>(up - a - 1) + (b1 - b0);
      if (near.size() < need) near.resize(need);
      uint32_t* pick = near.data();
      std::size_t k = 0;
      auto gather = [&](uint32_t q0, uint32_t q1) {
        for (uint32_t q = q0; q < q1; ++q) {
          const Box& B = box[q].box;
          pick[k] = q;
          k += static_cast<unsigned>(A.x0 <= B.x1) & static_cast<unsigned>(B.x0 <= A.x1) &
               static_cast<unsigned>(A.y0 <= B.y1) & static_cast<unsigned>(B.y0 <= A.y1);
        }
      };
      gather(static_cast<uint32_t>(a + 1), up);
      gather(b0, b1);
      const Body& P = body[a];
      const uint32_t ida = box[a].id;
      for (std::size_t m = 0; m < k; ++m) {
        const uint32_t q = pick[m];
        const Body& Q = body[q];
        if (P.w == 0.0 && Q.w == 0.0) continue;
        ++candidates;
        const uint32_t idq = box[q].id;
        const bool first = ida < idq;
        const Body &I = first ? P : Q, &J = first ? Q : P;
        double tau = 0.0;
        if (toi_refs(I.ref, J.ref, I.r + J.r, 0.0, dt, tau))
          out.push_back({tau, first ? ida : idq, first ? idq : ida});
      }
    }
    chunk_candidates_[c] = candidates;
  };
  if (threads)
    for_chunks(entries, kEntries, scan);
  else
    for (std::size_t c = 0; c < echunks; ++c)
      scan(c, c * kEntries, std::min(entries, (c + 1) * kEntries));
  std::size_t total = 0;
  for (std::size_t c = 0; c < echunks; ++c) {
    total += chunk_hits_[c].size();
    counts_.candidates += chunk_candidates_[c];
  }
  hits_.reserve(total);
  for (const auto& h : chunk_hits_) hits_.insert(hits_.end(), h.begin(), h.end());
  counts_.hits = hits_.size();
}

// The keys (tau, i, j) are unique, so any correct sort gives the same order. A counting sort
// by a bucket of tau that never decreases with tau (tau = 0 alone in bucket 0, then
// floor(tau B / dt) + 1, B = the number of hits), then each bucket sorted by the full key: a
// few hits per bucket but those touching at the start (tau = 0).
void PairContacts::order_hits(std::size_t n, bool threads, double dt) {
  auto before = [](const Hit& a, const Hit& b) {
    return a.tau < b.tau || (a.tau == b.tau && (a.i < b.i || (a.i == b.i && a.j < b.j)));
  };
  const std::size_t hits = hits_.size();
  if (hits < kBucketSort) {
    std::sort(hits_.begin(), hits_.end(), before);
    return;
  }
  const std::size_t buckets = hits + 1;
  const double scale = static_cast<double>(hits) / dt;
  auto bucket = [&](double tau) {
    return tau > 0.0 ? std::min(hits, 1 + static_cast<std::size_t>(tau * scale)) : 0;
  };
  std::vector<uint32_t>& start = fill_;
  start.assign(buckets + 1, 0);
  for (const Hit& h : hits_) ++start[bucket(h.tau) + 1];
  for (std::size_t k = 0; k < buckets; ++k) start[k + 1] += start[k];
  bucket_start_.assign(start.begin(), start.end());
  ordered_.resize(hits);
  for (const Hit& h : hits_) ordered_[start[bucket(h.tau)]++] = h;
  // each bucket in order: insertion sort for a few hits, else std::sort; on threads, runs of
  // buckets of about kSortHits hits apart (each writes only its own buckets)
  auto sort_buckets = [&](std::size_t k0, std::size_t k1) {
    if (k0 == 0 && k1 > 0) {
      sort_touching(n);
      k0 = 1;
    }
    for (std::size_t k = k0; k < k1; ++k) {
      Hit* b = ordered_.data() + bucket_start_[k];
      Hit* e = ordered_.data() + bucket_start_[k + 1];
      if (e - b > 16) {
        std::sort(b, e, before);
        continue;
      }
      for (Hit* p = b + 1; p < e; ++p)
        for (Hit* q = p; q > b && before(*q, *(q - 1)); --q) std::swap(*q, *(q - 1));
    }
  };
  if (threads && hits >= kParallelWave) {
    const std::size_t parts = chunk_count(hits, kSortHits);
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

// Bucket 0 of order_hits (tau = 0: the hits that touch at the start) in order of (i, j): a
// counting sort by i, then each run of one i (a particle's few neighbours) by j.
void PairContacts::sort_touching(std::size_t n) {
  Hit* b = ordered_.data();
  const std::size_t count = bucket_start_[1];
  if (count <= 16) {
    std::sort(b, b + count,
              [](const Hit& p, const Hit& q) { return p.i < q.i || (p.i == q.i && p.j < q.j); });
    return;
  }
  std::vector<uint32_t>& start = touch_start_;
  start.assign(n + 1, 0);
  for (std::size_t h = 0; h < count; ++h) ++start[b[h].i + 1];
  for (std::size_t i = 0; i < n; ++i) start[i + 1] += start[i];
  touching_.resize(count);
  for (std::size_t h = 0; h < count; ++h) touching_[start[b[h].i]++] = b[h];
  for (std::size_t h = 0; h < count;) {  // runs of one i (start[i] now ends i's run)
    const uint32_t i = touching_[h].i;
    const std::size_t e = start[i];
    for (std::size_t p = h + 1; p < e; ++p)
      for (std::size_t q = p; q > h && touching_[q].j < touching_[q - 1].j; --q)
        std::swap(touching_[q], touching_[q - 1]);
    h = e;
  }
  std::copy(touching_.begin(), touching_.end(), b);
}

// The time of impact of two discs in linear motion, |dx + dv tau| = r_i + r_j:
// a tau^2 + 2 b tau + c = 0 with a = dv.dv, b = dx.dv, c = dx.dx - (r_i + r_j)^2, the first
// root tau = (-b - sqrt(b^2 - a c)) / a written as c / (-b + sqrt(b^2 - a c)) (no
// cancellation); already touching (c <= 0) and approaching: tau0.
inline bool PairContacts::toi(const MutableState& s, uint32_t i, uint32_t j, double tau0, double dt,
                              double& tau) const {
  return toi_refs(ref_[i], ref_[j], s.radius[i] + s.radius[j], tau0, dt, tau);
}

bool PairContacts::toi_refs(const Ref& ri, const Ref& rj, double rr, double tau0, double dt,
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

// The impulse J = -(1 + e) vn / (w_i + w_j) along the normal n from j to i at the time of
// impact (w: inverse masses, 0 for pinned particles), as velocity changes J w_i n and
// -J w_j n; the reference states move to the contact.
void PairContacts::resolve_hit(const MutableState& s, std::size_t h, double dt, double e) {
  const uint32_t i = hits_[h].i, j = hits_[h].j;
  Outcome& out = outcome_[h];
  out.fired = false;
  Ref &ri = ref_[i], &rj = ref_[j];
  double tau = 0.0;
  if (!toi(s, i, j, std::max(ri.tr, rj.tr), dt, tau)) return;
  const Vec2 pi = ri.xr + ri.vc * (tau - ri.tr), pj = rj.xr + rj.vc * (tau - rj.tr);
  const Vec2 dx = pi - pj;
  const double l = dx.norm();
  const Vec2 nrm = l > 0.0 ? Vec2(dx / l) : Vec2(0.0, 1.0);
  const double vn = (ri.vc - rj.vc).dot(nrm);
  if (vn >= 0.0) return;
  const double wi = s.inv_mass[i], wj = s.inv_mass[j];
  const double jn = -(1.0 + e) * vn / (wi + wj);
  const Vec2 dvi = jn * wi * nrm, dvj = -jn * wj * nrm;
  if (tape_ != nullptr)
    tape_->pair(i, j, tau, ri.xr, ri.vc, ri.tr, rj.xr, rj.vc, rj.tr, s.radius[i] + s.radius[j], wi,
                wj, e);
  ri.xr = pi;
  rj.xr = pj;
  ri.tr = rj.tr = tau;
  ri.vc += dvi;
  rj.vc += dvj;
  out.fired = true;
  out.tau = tau;
  out.dvi = dvi;
  out.dvj = dvj;
  pinsim_event& ev = out.event;
  ev = pinsim_event{};
  ev.t = sim_t_ + tau;
  ev.particle = i;
  ev.obstacle = -1;
  ev.other = j;
  const Vec2 pt = pj + s.radius[j] * nrm;
  ev.point[0] = pt.x();
  ev.point[1] = pt.y();
  ev.normal[0] = nrm.x();
  ev.normal[1] = nrm.y();
  ev.vn_before = vn;
  ev.vn_after = (ri.vc - rj.vc).dot(nrm);
}

void PairContacts::resolve(const MutableState& s, double dt, double e, bool threads) {
  const std::size_t hits = hits_.size();
  outcome_.resize(hits);
  // Waves: a hit goes one wave after the last of its particles' earlier hits.
  last_level_.assign(s.n, 0);
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
  if (!threads || hits < kParallelWave) {  // one thread: the order of the hits is a schedule
    for (std::size_t h = 0; h < hits; ++h) resolve_hit(s, h, dt, e);
    return;
  }
  if (resolve_islands(s, dt, e)) return;
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
      for (std::size_t k = k0; k < k1; ++k) resolve_hit(s, by_level_[b + k], dt, e);
    };
    if (count >= kParallelWave)
      for_chunks(count, kWaveHits, wave);
    else
      wave(0, 0, count);
  }
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
    for (uint32_t k = task_start_[t]; k < task_start_[t + 1]; ++k)
      resolve_hit(s, by_level_[k], dt, e);
  });
  return true;
}

void PairContacts::collect(const MutableState& s, EventSink& ev) {
  const std::size_t n = s.n;
  change_start_.assign(n + 1, 0);
  for (std::size_t h = 0; h < hits_.size(); ++h) {
    if (!outcome_[h].fired) continue;
    if (s.inv_mass[hits_[h].i] > 0.0) ++change_start_[hits_[h].i + 1];
    if (s.inv_mass[hits_[h].j] > 0.0) ++change_start_[hits_[h].j + 1];
  }
  for (std::size_t i = 0; i < n; ++i) change_start_[i + 1] += change_start_[i];
  changes_.resize(change_start_[n]);
  std::vector<std::size_t>& fill = fill_changes_;
  fill.assign(change_start_.begin(), change_start_.end() - 1);
  for (std::size_t h = 0; h < hits_.size(); ++h) {
    const Outcome& o = outcome_[h];
    if (!o.fired) continue;
    const Hit& hit = hits_[h];
    if (s.inv_mass[hit.i] > 0.0) changes_[fill[hit.i]++] = {o.tau, o.dvi};
    if (s.inv_mass[hit.j] > 0.0) changes_[fill[hit.j]++] = {o.tau, o.dvj};
    ++counts_.impulses;
    ev.emit(o.event);
  }
}

}  // namespace pinsim::sdf
