// The first stage of the pair contacts (pair_contacts.cpp): the step's candidate pairs and
// hits, from a list of nearby pairs kept over the steps (a Verlet list with skin, as
// molecular dynamics keeps its neighbours; Box2D's broad phase keeps enlarged boxes the
// same way).
#include <algorithm>
#include <cmath>
#include <limits>
#include <pinsim/parallel.hpp>
#include <pinsim/scene_field/limits.hpp>
#include <string>

#include "pair_contacts.hpp"

namespace pinsim::sdf {

namespace {
/// Particles per chunk of the per-particle loops; entries per chunk of the grid's scan (any
/// value gives the same bits).
constexpr std::size_t kParticles = 1024;
constexpr std::size_t kEntries = 512;
/// Listed pairs per chunk of the scan (any value gives the same hits in the same order).
constexpr std::size_t kScanEntries = 2048;
/// At most this many parts of the particles (by index) whose runs in the list are built
/// apart, on threads (any value gives the same list).
constexpr std::size_t kListParts = 16;
constexpr uint32_t kNoCell = ~0u;
/// A particle's enlarged box: its swept box, also swept kAhead steps further at its
/// velocity, grown on every side by kSkin times the swept box's larger side. The larger they
/// are, the longer a list lasts and the more pairs it holds; any values give the same hits.
constexpr double kAhead = 8.0;
constexpr double kSkin = 0.125;
/// The most particles outside their enlarged boxes that a step gives new boxes in place
/// (each looks for its pairs in the build's grid and among the particles moved before); more
/// build the list anew, as do more than (n + kMovedFloor) / kMovedShare particles moved since
/// the build (each leaver compares its box with all of those).
constexpr std::size_t kMoves = 32;
constexpr std::size_t kMovedShare = 8;
constexpr std::size_t kMovedFloor = 1024;
/// Steps after which a kept list is built anew all the same (its boxes may have been grown
/// for motion that has since stopped; a build costs about as much as 3 steps of the scan).
constexpr std::size_t kKeep = 128;

bool finite_box(double x0, double x1, double y0, double y1) {
  return std::isfinite(x0) && std::isfinite(x1) && std::isfinite(y0) && std::isfinite(y1);
}

/// Whether two closed boxes overlap (callers leave boxes of NaN out first).
template <class B>
bool overlap(const B& a, const B& b) {
  return a.x0 <= b.x1 && b.x0 <= a.x1 && a.y0 <= b.y1 && b.y0 <= a.y1;
}

/// for_chunks on threads, else the same chunks in order on this thread (a drift recording
/// takes the hits in their order).
template <class Body>
void chunked(bool threads, std::size_t n, std::size_t chunk, Body&& body,
             Schedule schedule = Schedule::Dynamic) {
  if (threads) {
    for_chunks(n, chunk, body, schedule);
    return;
  }
  for (std::size_t c = 0; c < chunk_count(n, chunk); ++c)
    body(c, c * chunk, std::min(n, (c + 1) * chunk));
}
}  // namespace

// The hits are the pairs whose swept boxes overlap and that meet within the step. Whether a
// pair is listed never changes them: the list holds every pair whose enlarged boxes overlap,
// and while each swept box lies inside its particle's enlarged box two swept boxes that
// overlap belong to such a pair. A particle whose swept box is not inside gets a new
// enlarged box: up to kMoves of them in place (move_in_list), more (or a new particle count,
// or no list yet, or a list grown a quarter larger by such moves, or an eighth of the
// particles moved, or one kept kKeep steps: boxes grown for motion that has since stopped)
// build the list anew.
std::size_t PairContacts::find_hits(const MutableState& s, double dt, bool threads,
                                    double max_travel) {
  const bool kept = sweep(s, dt, threads, max_travel);
  if (too_fast_ < s.n) return too_fast_;
  counts_.rebuilt = !kept || leavers_.size() > kMoves || steps_kept_ >= kKeep ||
                    4 * (dead_ + extra_.size()) > list_.size() + 256 ||
                    kMovedShare * (moved_ids_.size() + leavers_.size()) > listed_n_ + kMovedFloor;
  steps_kept_ = counts_.rebuilt ? 0 : steps_kept_ + 1;
  if (counts_.rebuilt) {
    build_list(s, dt, threads);
  } else if (!leavers_.empty()) {
    move_in_list(dt);
    counts_.moved = leavers_.size();
  }
  counts_.listed = list_.size() - dead_ + extra_.size();
  scan_list(dt, threads);
  return s.n;
}

// Start states, and the particles whose swept box is not inside their enlarged box (at most
// kMoves + 1 per chunk: more build the list anew anyway). False if there is no list for
// these particles. On the way each chunk's first particle too fast (find()): the first of
// them in chunk order is the first in index order.
bool PairContacts::sweep(const MutableState& s, double dt, bool threads, double max_travel) {
  const std::size_t n = s.n;
  start_.resize(n);
  const bool listed = listed_n_ == n;
  const std::size_t chunks = chunk_count(n, kParticles);
  chunk_leavers_.resize(std::max(chunk_leavers_.size(), chunks));
  chunk_too_fast_.assign(chunks, n);
  const bool check = max_travel < HUGE_VAL;
  auto sweep_chunk = [&](std::size_t c, std::size_t b, std::size_t end) {
    std::vector<uint32_t>& out = chunk_leavers_[c];
    out.clear();
    std::size_t fast = n;
    for (std::size_t i = b; i < end; ++i) {
      const bool moves = s.inv_mass[i] > 0.0;
      const Start p{s.x(0, i),   s.x(1, i),    moves ? s.v(0, i) : 0.0, moves ? s.v(1, i) : 0.0,
                    s.radius[i], s.inv_mass[i]};
      start_[i] = p;
      if (check && moves && fast == n && travels_beyond(p.vx, p.vy, dt, max_travel)) fast = i;
      if (!listed || out.size() > kMoves) continue;
      // a particle left out of the list (no finite box) must still have none
      const Box bx = swept_box(p, dt);
      const Box& f = fat_[i];
      const bool inside = finite_box(bx.x0, bx.x1, bx.y0, bx.y1)
                              ? !std::isnan(f.x0) && f.x0 <= bx.x0 && bx.x1 <= f.x1 &&
                                    f.y0 <= bx.y0 && bx.y1 <= f.y1
                              : std::isnan(f.x0);
      if (!inside) out.push_back(static_cast<uint32_t>(i));
    }
    chunk_too_fast_[c] = fast;
  };
  chunked(threads, n, kParticles, sweep_chunk, Schedule::Even);
  too_fast_ = n;
  for (const std::size_t i : chunk_too_fast_)
    if (i < n) {
      too_fast_ = i;
      break;
    }
  leavers_.clear();
  for (std::size_t c = 0; c < chunks && leavers_.size() <= kMoves; ++c)
    leavers_.insert(leavers_.end(), chunk_leavers_[c].begin(), chunk_leavers_[c].end());
  return listed;
}

// The enlarged box: the swept box, also swept kAhead steps further at the particle's
// velocity, grown by kSkin times its larger side (the swept box itself if that is beyond the
// doubles).
PairContacts::Box PairContacts::enlarged(std::size_t i, double dt) const {
  const Box bx = swept_box(start_[i], dt);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (!finite_box(bx.x0, bx.x1, bx.y0, bx.y1)) return {nan, nan, nan, nan};
  const Vec2 ahead = kAhead * dt * Vec2(start_[i].vx, start_[i].vy);
  const double m = kSkin * std::max(bx.x1 - bx.x0, bx.y1 - bx.y0);
  const Box f{bx.x0 + std::min(ahead.x(), 0.0) - m, bx.x1 + std::max(ahead.x(), 0.0) + m,
              bx.y0 + std::min(ahead.y(), 0.0) - m, bx.y1 + std::max(ahead.y(), 0.0) + m};
  return finite_box(f.x0, f.x1, f.y0, f.y1) ? f : bx;
}

// The list is then: its entries not retired (pairs whose boxes are those of the last build)
// and extra_ (every pair with a moved particle whose boxes overlap now). A retired entry
// holds its own run's particle, a pair the scan never takes. A leaver's entries are those in
// its own run and, if it has not moved since the build, those in the runs of the lower
// particles whose box met its build box (a moved particle's runs are retired already): found
// in the build's grid. Its new pairs are with the particles that have not moved (their boxes
// are in the grid) and those that have (moved_ids_), a pair of two leavers once.
void PairContacts::move_in_list(double dt) {
  for (const uint32_t i : leavers_) leaving_[i] = 1;
  std::erase_if(extra_, [&](const auto& p) { return leaving_[p.first] || leaving_[p.second]; });
  for (const uint32_t i : leavers_) {
    for (uint32_t k = list_start_[i]; k < list_start_[i + 1]; ++k)
      if (list_[k].second != i) {
        list_[k].second = i;
        ++dead_;
      }
    const Box old = fat_[i];
    if (moved_[i] == 0 && !std::isnan(old.x0))
      in_grid(old, [&](uint32_t j) {
        if (j >= i || moved_[j] != 0 || leaving_[j] != 0) return;
        for (uint32_t k = list_start_[j]; k < list_start_[j + 1]; ++k)
          if (list_[k].second == i) {
            list_[k].second = j;
            ++dead_;
          }
      });
    fat_[i] = enlarged(i, dt);
  }
  auto pair = [&](uint32_t i, uint32_t j) { extra_.emplace_back(std::min(i, j), std::max(i, j)); };
  for (const uint32_t i : leavers_) {
    const Box& now = fat_[i];
    if (std::isnan(now.x0)) continue;
    in_grid(now, [&](uint32_t j) {
      if (moved_[j] == 0 && leaving_[j] == 0 && overlap(now, fat_[j])) pair(i, j);
    });
    for (const uint32_t j : moved_ids_)
      if (leaving_[j] == 0 && !std::isnan(fat_[j].x0) && overlap(now, fat_[j])) pair(i, j);
    for (const uint32_t j : leavers_) {
      if (j >= i) break;  // (in increasing order)
      if (!std::isnan(fat_[j].x0) && overlap(now, fat_[j])) pair(i, j);
    }
  }
  for (const uint32_t i : leavers_) {
    leaving_[i] = 0;
    if (moved_[i] == 0) moved_ids_.push_back(i);
    moved_[i] = 1;
  }
}

// Calls f(j) for each particle j whose box in the build's grid may overlap box b (finite):
// its home cell (that of its lower corner, at most the cell size below b's) within the cells
// of [b.x0 - h, b.x1] x [b.y0 - h, b.y1], one more on each side for rounding.
template <class F>
void PairContacts::in_grid(const Box& b, F&& f) const {
  if (grid_nx_ == 0) return;
  const double h = grid_h_;
  auto range = [h](double lo, double hi, double origin, std::size_t cells) {
    const double top = static_cast<double>(cells - 1);
    const double c0 = std::clamp(std::floor((lo - h - origin) / h) - 1.0, 0.0, top);
    const double c1 = std::clamp(std::floor((hi - origin) / h) + 1.0, 0.0, top);
    return std::pair{static_cast<std::size_t>(c0), static_cast<std::size_t>(c1)};
  };
  const auto [cx0, cx1] = range(b.x0, b.x1, grid_x0_, grid_nx_);
  const auto [cy0, cy1] = range(b.y0, b.y1, grid_y0_, grid_ny_);
  for (std::size_t cx = cx0; cx <= cx1; ++cx) {
    const std::size_t first = cx * grid_ny_;
    for (uint32_t q = cell_start_[first + cy0]; q < cell_start_[first + cy1 + 1]; ++q)
      f(sorted_[q].id);
  }
}

void PairContacts::build_list(const MutableState& s, double dt, bool threads) {
  const std::size_t n = s.n;
  fat_.resize(n);
  cell_of_.resize(n);
  list_start_.assign(n + 1, 0);
  list_.clear();
  extra_.clear();
  dead_ = 0;
  listed_n_ = n;
  moved_.assign(n, 0);
  leaving_.assign(n, 0);
  moved_ids_.clear();
  grid_nx_ = 0;
  // Enlarged boxes; bounds and the largest extent of the finite ones (min and max are
  // exact, so per-chunk partials combine to the same values in any order).
  struct Extent {
    double x0 = HUGE_VAL, y0 = HUGE_VAL, x1 = -HUGE_VAL, y1 = -HUGE_VAL, size = 0.0;
  };
  const std::size_t pchunks = chunk_count(n, kParticles);
  std::vector<Extent> part(pchunks);
  auto enlarge = [&](std::size_t c, std::size_t b, std::size_t end) {
    Extent ex;
    for (std::size_t i = b; i < end; ++i) {
      const Box f = enlarged(i, dt);
      fat_[i] = f;
      if (std::isnan(f.x0)) {
        cell_of_[i] = kNoCell;
        continue;
      }
      cell_of_[i] = 0;
      ex.x0 = std::min(ex.x0, f.x0);
      ex.y0 = std::min(ex.y0, f.y0);
      ex.x1 = std::max(ex.x1, f.x1);
      ex.y1 = std::max(ex.y1, f.y1);
      ex.size = std::max({ex.size, f.x1 - f.x0, f.y1 - f.y0});
    }
    part[c] = ex;
  };
  chunked(threads, n, kParticles, enlarge, Schedule::Even);
  Extent all;
  for (const Extent& ex : part) {
    all.x0 = std::min(all.x0, ex.x0);
    all.y0 = std::min(all.y0, ex.y0);
    all.x1 = std::max(all.x1, ex.x1);
    all.y1 = std::max(all.y1, ex.y1);
    all.size = std::max(all.size, ex.size);
  }
  if (!(all.x0 <= all.x1)) return;  // no finite box: an empty list
  // A uniform grid whose cells are a little larger than the largest box (so rounding in the
  // cell index cannot put two overlapping boxes two cells apart), at most about 4 n of
  // them: two boxes that overlap have home cells (the cell of the lower corner) at most one
  // apart.
  const double w = all.x1 - all.x0, hgt = all.y1 - all.y0;
  double h = all.size * (1.0 + 1e-6);
  if (!(h > 0.0)) h = std::max({w, hgt, 1e-300});
  const double limit = 4.0 * static_cast<double>(n) + 16.0;
  while ((std::floor(w / h) + 1.0) * (std::floor(hgt / h) + 1.0) > limit) h *= 1.5;
  const auto nx = static_cast<std::size_t>(std::floor(w / h)) + 1;
  const auto ny = static_cast<std::size_t>(std::floor(hgt / h)) + 1;
  const std::size_t cells = nx * ny;
  grid_x0_ = all.x0;
  grid_y0_ = all.y0;
  grid_h_ = h;
  grid_nx_ = nx;
  grid_ny_ = ny;
  // Counting sort of the boxes by home cell, cells column by column (cell cx ny + cy), in
  // increasing particle index within a cell: a cell and the one above it, and the three
  // cells of the next column beside them, are each one contiguous run.
  cell_start_.assign(cells + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (cell_of_[i] == kNoCell) continue;
    const auto cx = std::min(nx - 1, static_cast<std::size_t>((fat_[i].x0 - all.x0) / h));
    const auto cy = std::min(ny - 1, static_cast<std::size_t>((fat_[i].y0 - all.y0) / h));
    cell_of_[i] = static_cast<uint32_t>(cx * ny + cy);
    ++cell_start_[cell_of_[i] + 1];
  }
  for (std::size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
  const std::size_t entries = cell_start_[cells];
  sorted_.resize(entries);
  fill_.assign(cell_start_.begin(), cell_start_.end() - 1);
  for (std::size_t i = 0; i < n; ++i) {
    const uint32_t c = cell_of_[i];
    if (c == kNoCell) continue;
    // the runs of this cell's neighbours: up to the end of the cell above, and the cells of
    // the next column from the row below to the row above
    const std::size_t cx = c / ny, cy = c % ny, right = c + ny;
    const uint32_t up = cell_start_[cy + 1 < ny ? c + 2 : c + 1];
    const bool next = cx + 1 < nx;
    const uint32_t b0 = next ? cell_start_[cy > 0 ? right - 1 : right] : 0;
    const uint32_t b1 = next ? cell_start_[cy + 1 < ny ? right + 2 : right + 1] : 0;
    sorted_[fill_[c]++] = {fat_[i], static_cast<uint32_t>(i), up, b0, b1};
  }
  // Each entry against the later entries of its cell and the cell above, and the cells
  // (+1, -1), (+1, 0), (+1, +1): each pair of cells at most one apart is seen once. The boxes
  // that overlap are gathered without branches. Each chunk's pairs go to the part of their
  // lower index (particles [p 2^shift, (p + 1) 2^shift): part p).
  unsigned shift = 0;
  while ((n - 1) >> shift >= kListParts) ++shift;
  const std::size_t parts = ((n - 1) >> shift) + 1;
  const std::size_t echunks = chunk_count(entries, kEntries);
  chunk_pairs_.resize(echunks * parts);
  chunk_near_.resize(echunks);
  auto scan = [&](std::size_t c, std::size_t b, std::size_t end) {
    auto* out = chunk_pairs_.data() + c * parts;
    std::vector<uint32_t>& near = chunk_near_[c];
    for (std::size_t p = 0; p < parts; ++p) out[p].clear();
    const Sorted* box = sorted_.data();
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
      const uint32_t ida = box[a].id;
      for (std::size_t m = 0; m < k; ++m) {
        const uint32_t idq = box[pick[m]].id, lo = std::min(ida, idq);
        out[lo >> shift].emplace_back(lo, std::max(ida, idq));
      }
    }
  };
  chunked(threads, entries, kEntries, scan);
  // The pairs by lower index, each particle's partners in increasing order (so the scan
  // finds the hits that touch at the start in the order order_hits puts them in).
  std::size_t found = 0;
  for (const auto& pairs : chunk_pairs_) found += pairs.size();
  if (found > std::numeric_limits<uint32_t>::max()) {
    listed_n_ = kNoList;  // no list: the next step builds again
    throw Error("sdf backend: " + std::to_string(found) +
                " pairs of particles within reach of each other, more than the pair contacts "
                "can list (4294967295)");
  }
  // Each part's runs apart (a counting sort of its pairs by lower index from its place on,
  // the parts' places from their sizes), then each run in order of the partner.
  part_start_.assign(parts + 1, 0);
  for (std::size_t p = 0; p < parts; ++p) {
    std::size_t size = 0;
    for (std::size_t c = 0; c < echunks; ++c) size += chunk_pairs_[c * parts + p].size();
    part_start_[p + 1] = part_start_[p] + static_cast<uint32_t>(size);
  }
  list_.resize(found);
  list_start_[n] = static_cast<uint32_t>(found);
  fill_.resize(n);
  chunked(threads, parts, 1, [&](std::size_t p, std::size_t, std::size_t) {
    const std::size_t i0 = p << shift, i1 = std::min(n, (p + 1) << shift);
    uint32_t* count = fill_.data();
    std::fill(count + i0, count + i1, 0u);
    for (std::size_t c = 0; c < echunks; ++c)
      for (const auto& pair : chunk_pairs_[c * parts + p]) ++count[pair.first];
    uint32_t at = part_start_[p];
    for (std::size_t i = i0; i < i1; ++i) {
      list_start_[i] = at;
      at += count[i];
      count[i] = list_start_[i];  // (now where its next pair goes)
    }
    for (std::size_t c = 0; c < echunks; ++c)
      for (const auto& pair : chunk_pairs_[c * parts + p]) list_[count[pair.first]++] = pair;
    for (std::size_t i = i0; i < i1; ++i) {  // a few partners each: insertion sort
      auto* run = list_.data() + list_start_[i];
      const std::size_t size =
          (i + 1 < i1 ? list_start_[i + 1] : part_start_[p + 1]) - list_start_[i];
      for (std::size_t q0 = 1; q0 < size; ++q0)
        for (std::size_t q = q0; q > 0 && run[q].second < run[q - 1].second; --q)
          std::swap(run[q], run[q - 1]);
    }
  });
}

// Each listed pair (i < j): candidates are the pairs whose closed swept boxes overlap (not
// both pinned), hits those that meet within the step with the velocities at its start; in
// fixed chunks of the list, then in chunk order (order_hits sorts them).
// Without branches on the outcome: first each listed pair's box test and a bound that
// rules most candidates out without the root (below), counting the candidates and gathering
// those left; then their times of impact as toi_refs gives them (the same bits).
// With a = dv.dv, b = dx.dv, c = dx.dx - (r_i + r_j)^2 (toi_refs), apart (c > 0) and
// approaching (b < 0), the first root tau* of a tau^2 + 2 b tau + c has
// c = -2 b tau* - a tau*^2 <= 2 |b| tau*, so tau* >= c / (2 |b|): when c + 2 b dt > 0 by a
// relative margin of 1e-6 the root is beyond dt by more than the rounding of the formula's
// c / (-b + sqrt(b^2 - a c)) (a few ulps, 2e-8 relatively where b^2 - a c cancels), so the
// pair is no hit. (The computed root's denominator is at most 2 |b|, so a root the rounding
// makes real is beyond dt too.) The box test and the bound: look() (pair_look.hpp).

// The time of impact of each pair (ni[m], nj[m]) left by look(), as toi_refs gives it at
// tau0 = 0 (reference times 0): touching (and approaching) gives 0, else the first root
// c / (-b + sqrt(b^2 - a c)) if real and within the step. First the touching pairs out as
// hits (in their order) and the others gathered to the front of ni, nj; then the roots of
// those, computed for each without branches and kept where they apply (most pairs of a pile
// touch: they need no root).
std::size_t PairContacts::times_of_impact(uint32_t* ni, uint32_t* nj, std::size_t k, double dt,
                                          std::vector<Hit>& out) const {
  out.resize(k);
  std::size_t hits = 0, apart = 0;
  for (std::size_t m = 0; m < k; ++m) {
    const uint32_t i = ni[m], j = nj[m];
    const Start &P = start_[i], &Q = start_[j];
    const double dx = P.x - Q.x, dy = P.y - Q.y, rr = P.r + Q.r;
    const bool is_apart = (dx * dx + dy * dy) - rr * rr > 0.0;  // (all are approaching)
    out[hits] = {0.0, i, j};
    ni[apart] = i;
    nj[apart] = j;
    hits += static_cast<unsigned>(!is_apart);
    apart += static_cast<unsigned>(is_apart);
  }
  const std::size_t touching = hits;
  for (std::size_t m = 0; m < apart; ++m) {
    const uint32_t i = ni[m], j = nj[m];
    const Start &P = start_[i], &Q = start_[j];
    const double dx = P.x - Q.x, dy = P.y - Q.y, dvx = P.vx - Q.vx, dvy = P.vy - Q.vy;
    const double rr = P.r + Q.r;
    const double qa = dvx * dvx + dvy * dvy, qb = dx * dvx + dy * dvy;
    const double qc = (dx * dx + dy * dy) - rr * rr;
    const double disc = qb * qb - qa * qc;
    const double root = qc / (-qb + std::sqrt(std::max(disc, 0.0)));
    out[hits] = {root, i, j};
    hits += static_cast<unsigned>(disc >= 0.0) & static_cast<unsigned>(root <= dt);
  }
  out.resize(hits);
  return touching;
}

void PairContacts::scan_list(double dt, bool threads) {
  const std::size_t entries = list_.size();
  const std::size_t chunks = chunk_count(entries, kScanEntries);
  chunk_hits_.resize(chunks + 1);
  chunk_candidates_.assign(chunks + 1, 0);
  chunk_touching_.assign(chunks + 1, 0);
  chunk_near_.resize(std::max(chunk_near_.size(), chunks + 1));
  // pairs [p, p + count) as chunk c
  auto scan = [&](std::size_t c, const std::pair<uint32_t, uint32_t>* pairs, std::size_t count) {
    std::vector<uint32_t>& near = chunk_near_[c];
    if (near.size() < 2 * count) near.resize(2 * count);
    uint32_t* ni = near.data();
    uint32_t* nj = ni + count;
    const Start* p = start_.data();
    std::size_t candidates = 0, k = 0;
    for (std::size_t m = 0; m < count; ++m) {
      const uint32_t i = pairs[m].first, j = pairs[m].second;
      if (j == i) continue;  // retired
      unsigned candidate = 0;
      const unsigned left = look(p[i], p[j], dt, candidate);
      ni[k] = i;
      nj[k] = j;
      candidates += candidate;
      k += left;
    }
    chunk_candidates_[c] = candidates;
    chunk_touching_[c] = times_of_impact(ni, nj, k, dt, chunk_hits_[c]);
  };
  chunked(threads, entries, kScanEntries, [&](std::size_t c, std::size_t b, std::size_t end) {
    scan(c, list_.data() + b, end - b);
  });
  scan(chunks, extra_.data(), extra_.size());  // the moved particles' pairs, as one more chunk
  // The hits out of the chunks in chunk order: those touching at the start into ordered_,
  // the others into later_ (a root that rounds to 0 counts as touching: tau = 0); on the way
  // each particle in a hit marked (kTouching, kLate: the kinds of its hits), its reference
  // state to start at time 0 (resolve()).
  const std::size_t n = start_.size();
  in_hit_.assign(n, 0);
  ref_t_.resize(n);
  auto mark = [&](const Hit& h, char flag) {
    in_hit_[h.i] |= flag;
    in_hit_[h.j] |= flag;
    ref_t_[h.i] = ref_t_[h.j] = 0.0;
  };
  std::size_t total = 0;
  for (std::size_t c = 0; c < chunk_hits_.size(); ++c) {
    total += chunk_hits_[c].size();
    counts_.candidates += chunk_candidates_[c];
  }
  ordered_.resize(total);
  later_.resize(total);
  std::size_t touching = 0, apart = 0;
  for (std::size_t c = 0; c < chunk_hits_.size(); ++c) {
    const std::vector<Hit>& h = chunk_hits_[c];
    for (std::size_t m = 0; m < chunk_touching_[c]; ++m) {
      ordered_[touching++] = h[m];
      mark(h[m], kTouching);
    }
    for (std::size_t m = chunk_touching_[c]; m < h.size(); ++m) {
      const bool is_later = h[m].tau > 0.0;
      mark(h[m], is_later ? kLate : kTouching);
      ordered_[touching] = h[m];
      later_[apart] = h[m];
      touching += static_cast<std::size_t>(!is_later);
      apart += static_cast<std::size_t>(is_later);
    }
  }
  touching_n_ = touching;
  later_n_ = apart;
  counts_.hits = total;
}

}  // namespace pinsim::sdf
