// PairContacts (the sdf backend's particle-particle contacts) against a brute-force serial
// reference: every pair whose swept boxes overlap, the time of impact of two discs in
// linear motion tau = c / (-b + sqrt(b^2 - a c)) (a = dv.dv, b = dx.dv,
// c = dx.dx - (r_i + r_j)^2; README, Particle-particle contacts), the hits in order of
// (tau, i, j), each re-timed from its particles' states as updated by the earlier ones and
// given the impulse J = -(1 + e) vn / (w_i + w_j). The grid, the sort and the waves must give
// the same changes and events to the bit, on one thread and on 2 and 3.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <optional>
#include <pinsim/plugin.hpp>
#include <random>
#include <thread>
#include <vector>
#ifdef PINSIM_WITH_TBB
#include <tbb/global_control.h>
#endif

#include "pair_contacts.hpp"
#include "test_support.hpp"

using pinsim::EventSink;
using pinsim::MutableState;
using pinsim::Vec2;
using pinsim::sdf::PairContacts;

namespace {

struct Balls {
  std::vector<double> x, v, w, r;
  std::size_t n() const { return w.size(); }
  MutableState state(double t) {
    pinsim_state_mut sm{n(), t, x.data(), v.data(), w.data(), r.data()};
    return MutableState(sm);
  }
};

/// `n` balls crowded in a square of side `side` (many overlap or touch), random radii and
/// velocities, every 17th pinned.
Balls crowd(std::size_t n, double side, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, side), uv(-1.0, 1.0), ur(0.004, 0.012);
  Balls b;
  for (std::size_t i = 0; i < n; ++i) {
    b.x.insert(b.x.end(), {u(rng), u(rng)});
    b.v.insert(b.v.end(), {uv(rng), uv(rng)});
    b.w.push_back(i % 17 == 0 ? 0.0 : 1.0 / (0.5 + u(rng) / side));
    b.r.push_back(ur(rng));
  }
  return b;
}

struct Result {
  std::vector<std::vector<PairContacts::Change>> changes;
  std::vector<pinsim_event> events;
  std::size_t candidates = 0, hits = 0;  ///< pairs whose swept boxes overlap; of them, hits
};

/// The serial reference over all pairs (O(n^2)).
Result reference(const Balls& s, double t0, double dt, double e) {
  const std::size_t n = s.n();
  std::vector<Vec2> xr(n), vc(n);
  std::vector<double> tr(n, 0.0);
  struct Box {
    double x0, x1, y0, y1;
  };
  std::vector<Box> box(n);
  for (std::size_t i = 0; i < n; ++i) {
    xr[i] = Vec2(s.x[2 * i], s.x[2 * i + 1]);
    vc[i] = s.w[i] > 0.0 ? Vec2(s.v[2 * i], s.v[2 * i + 1]) : Vec2::Zero();
    const Vec2 a = xr[i], b = a + (s.w[i] > 0.0 ? Vec2(dt * vc[i]) : Vec2::Zero());
    box[i] = {std::min(a.x(), b.x()) - s.r[i], std::max(a.x(), b.x()) + s.r[i],
              std::min(a.y(), b.y()) - s.r[i], std::max(a.y(), b.y()) + s.r[i]};
  }
  auto toi = [&](std::size_t i, std::size_t j, double tau0, double& tau) {
    const Vec2 pi = xr[i] + vc[i] * (tau0 - tr[i]), pj = xr[j] + vc[j] * (tau0 - tr[j]);
    const Vec2 dx = pi - pj, dv = vc[i] - vc[j];
    const double rr = s.r[i] + s.r[j];
    const double a = dv.squaredNorm(), b = dx.dot(dv), c = dx.squaredNorm() - rr * rr;
    if (b >= 0.0) return false;
    if (c <= 0.0) {
      tau = tau0;
      return true;
    }
    const double disc = b * b - a * c;
    if (disc < 0.0) return false;
    tau = tau0 + c / (-b + std::sqrt(disc));
    return tau <= dt;
  };
  struct Hit {
    double tau;
    std::size_t i, j;
  };
  std::vector<Hit> hits;
  std::size_t candidates = 0;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j) {
      const Box &A = box[i], &B = box[j];
      if (!(A.x0 <= B.x1 && B.x0 <= A.x1 && A.y0 <= B.y1 && B.y0 <= A.y1)) continue;
      if (s.w[i] == 0.0 && s.w[j] == 0.0) continue;
      ++candidates;
      double tau = 0.0;
      if (toi(i, j, 0.0, tau)) hits.push_back({tau, i, j});
    }
  std::sort(hits.begin(), hits.end(), [](const Hit& a, const Hit& b) {
    return a.tau < b.tau || (a.tau == b.tau && (a.i < b.i || (a.i == b.i && a.j < b.j)));
  });
  Result out;
  out.candidates = candidates;
  out.hits = hits.size();
  out.changes.resize(n);
  for (const Hit& h : hits) {
    const std::size_t i = h.i, j = h.j;
    double tau = 0.0;
    if (!toi(i, j, std::max(tr[i], tr[j]), tau)) continue;
    const Vec2 pi = xr[i] + vc[i] * (tau - tr[i]), pj = xr[j] + vc[j] * (tau - tr[j]);
    const Vec2 dx = pi - pj;
    const double l = dx.norm();
    const Vec2 nrm = l > 0.0 ? Vec2(dx / l) : Vec2(0.0, 1.0);
    const double vn = (vc[i] - vc[j]).dot(nrm);
    if (vn >= 0.0) continue;
    const double wi = s.w[i], wj = s.w[j];
    const double jn = -(1.0 + e) * vn / (wi + wj);
    const Vec2 dvi = jn * wi * nrm, dvj = -jn * wj * nrm;
    xr[i] = pi;
    xr[j] = pj;
    tr[i] = tr[j] = tau;
    vc[i] += dvi;
    vc[j] += dvj;
    if (wi > 0.0) out.changes[i].push_back({tau, dvi});
    if (wj > 0.0) out.changes[j].push_back({tau, dvj});
    pinsim_event ev{};
    ev.t = t0 + tau;
    ev.particle = static_cast<int64_t>(i);
    ev.obstacle = -1;
    ev.other = static_cast<int64_t>(j);
    const Vec2 pt = pj + s.r[j] * nrm;
    ev.point[0] = pt.x();
    ev.point[1] = pt.y();
    ev.normal[0] = nrm.x();
    ev.normal[1] = nrm.y();
    ev.vn_before = vn;
    ev.vn_after = (vc[i] - vc[j]).dot(nrm);
    out.events.push_back(ev);
  }
  return out;
}

Result scheduled(Balls& s, double t0, double dt, double e, bool threads, PairContacts& pc) {
  std::vector<pinsim_event> events;
  const pinsim_event_sink sink{&events, [](void* c, const pinsim_event* ev) {
                                 static_cast<std::vector<pinsim_event>*>(c)->push_back(*ev);
                               }};
  EventSink es(&sink);
  const MutableState ms = s.state(t0);
  pc.schedule(ms, dt, e, threads, es);
  Result out;
  out.events = events;
  out.candidates = pc.counts().candidates;
  out.hits = pc.counts().hits;
  out.changes.resize(s.n());
  for (std::size_t i = 0; i < s.n(); ++i) {
    const auto c = pc.changes(i);
    out.changes[i].assign(c.begin(), c.end());
    CHECK(pc.changed(i) == !c.empty());
  }
  return out;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void require_same(const Result& a, const Result& b) {
  CHECK(a.candidates == b.candidates);  // each pair seen once
  CHECK(a.hits == b.hits);
  REQUIRE(a.events.size() == b.events.size());
  for (std::size_t k = 0; k < a.events.size(); ++k)
    REQUIRE(std::memcmp(&a.events[k], &b.events[k], sizeof(pinsim_event)) == 0);
  REQUIRE(a.changes.size() == b.changes.size());
  for (std::size_t i = 0; i < a.changes.size(); ++i) {
    REQUIRE(a.changes[i].size() == b.changes[i].size());
    for (std::size_t k = 0; k < a.changes[i].size(); ++k) {
      CHECK(same_bits(a.changes[i][k].tau, b.changes[i][k].tau));
      CHECK(same_bits(a.changes[i][k].dv.x(), b.changes[i][k].dv.x()));
      CHECK(same_bits(a.changes[i][k].dv.y(), b.changes[i][k].dv.y()));
    }
  }
}

}  // namespace

TEST_CASE("pair contacts: grid, sort and waves equal the serial all-pairs loop to the bit") {
  // 3000 balls in a 0.3 square (radii 4-12 mm, so each touches several), 1 m/s at most,
  // dt 5 ms (5 mm of travel): thousands of hits, chains of them through shared particles.
  for (unsigned seed : {1u, 2u, 3u}) {
    Balls b = crowd(3000, 0.3, seed);
    const double t0 = 0.25, dt = 5e-3, e = 0.5;
    const Result ref = reference(b, t0, dt, e);
    REQUIRE(ref.events.size() > 1000);  // a crowded step: the waves have work to share
    PairContacts pc;
    const Result one = scheduled(b, t0, dt, e, false, pc);
    require_same(ref, one);
    CHECK(pc.counts().impulses == ref.events.size());
#ifdef PINSIM_WITH_TBB
    for (std::size_t threads : {2u, 3u}) {
      const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
      const Result many = scheduled(b, t0, dt, e, true, pc);
      require_same(ref, many);
      CHECK(pc.counts().impulses == ref.events.size());
      // one crowd: one island with most of the hits, so the waves ran, chained through
      // shared particles
      CHECK(2 * pc.counts().largest_island > pc.counts().hits);
      CHECK(pc.counts().levels > 1);
    }
#endif
  }
}

TEST_CASE("pair contacts: a particle's changes are final once the resolution is past it") {
  // The backend marches a particle in hits as soon as resolved_below() passes it (and, if it
  // is late(), once every hit is resolved), while the hits are resolved on another thread.
  // Here a second thread resolves crowded steps (most hits touch at the start) while this
  // one copies each particle's changes as soon as that says they are final: every copy must
  // equal the changes at the end, to the bit.
  // (six crowds of 3000, then, until a copy was made before the end, crowds of 60,000 at the
  // same density: on a loaded machine this thread may not run while the other resolves a
  // step of 3000, well under a time slice; one of 60,000 takes a few ms)
  std::size_t early = 0, copied = 0, late = 0;
  for (unsigned round = 0; round < 6 || (early == 0 && round < 30); ++round) {
    const std::size_t balls = round < 6 ? 3000 : 60000;
    Balls b = crowd(balls, 0.3 * std::sqrt(static_cast<double>(balls) / 3000.0), 31 + round);
    const MutableState ms = b.state(0.0);
    const double dt = 2e-4;  // 0.2 mm of travel at most: few hits but those touching
    PairContacts pc;
    pc.find(ms, dt, false);
    CHECK(pc.resolved_below() == 0);  // nothing is final before the resolution
    Result copies, final_changes;     // (only their changes: require_same compares those)
    std::vector<std::vector<PairContacts::Change>>& at_final = copies.changes;
    at_final.resize(b.n());
    std::vector<char> done(b.n(), 0);
    std::size_t next = 0;  // particles below it copied
    auto copy = [&](std::size_t i) {
      const auto c = pc.changes(i);
      at_final[i].assign(c.begin(), c.end());
      done[i] = 1;
      ++copied;
    };
    std::thread resolver([&] {
      EventSink none(nullptr);
      pc.resolve_found(ms, dt, 0.5, false, none);
    });
    for (;;) {
      const std::size_t below = pc.resolved_below();
      const bool all = below == PairContacts::kAllResolved;
      for (; next < std::min(below, b.n()); ++next)
        if (pc.in_hit(next) && !pc.late(next)) {
          copy(next);
          early += !all;
        }
      if (all) break;
    }
    resolver.join();
    for (std::size_t i = 0; i < b.n(); ++i) {
      if (!pc.in_hit(i) || done[i] != 0) continue;
      late += pc.late(i);
      copy(i);
    }
    for (std::size_t i = 0; i < b.n(); ++i) {
      const auto c = pc.changes(i);
      final_changes.changes.emplace_back(c.begin(), c.end());
    }
    require_same(copies, final_changes);
  }
  // both kinds of hits: particles final early and particles that wait for every hit; some
  // copies made while the resolution was still going (how many depends on the timing)
  INFO("copied " << copied << ", of them before the end " << early << ", late " << late);
  CHECK(copied > 6000);
  CHECK(late > 0);
  CHECK(early > 0);
}

TEST_CASE("pair contacts: separate crowds run as islands, with the same bits") {
  // Eight crowds of 400 balls, 1 apart: eight islands of about equal size, none with half of
  // the hits, so on threads each island runs whole on one thread.
  Balls b;
  for (unsigned k = 0; k < 8; ++k) {
    Balls c = crowd(400, 0.15, 10 + k);
    for (std::size_t i = 0; i < c.n(); ++i) c.x[2 * i] += static_cast<double>(k);
    b.x.insert(b.x.end(), c.x.begin(), c.x.end());
    b.v.insert(b.v.end(), c.v.begin(), c.v.end());
    b.w.insert(b.w.end(), c.w.begin(), c.w.end());
    b.r.insert(b.r.end(), c.r.begin(), c.r.end());
  }
  const Result ref = reference(b, 1.0, 5e-3, 0.3);
  REQUIRE(ref.events.size() > 1000);
  PairContacts pc;
  require_same(ref, scheduled(b, 1.0, 5e-3, 0.3, false, pc));
#ifdef PINSIM_WITH_TBB
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  require_same(ref, scheduled(b, 1.0, 5e-3, 0.3, true, pc));
  CHECK(pc.counts().largest_island > 0);  // the islands ran
  CHECK(2 * pc.counts().largest_island <= pc.counts().hits);
#endif
}

TEST_CASE("pair contacts: a fast particle widens the grid's cells and is still found") {
  // One ball crossing the whole crowd in the step (its box the largest): every pair it meets
  // is found, as by the all-pairs loop.
  Balls b = crowd(400, 0.2, 7);
  b.x[2] = -0.05;
  b.x[3] = 0.1;
  b.v[2] = 60.0;  // 0.3 in 5 ms
  b.v[3] = 0.0;
  b.w[1] = 1.0;
  const Result ref = reference(b, 0.0, 5e-3, 1.0);
  PairContacts pc;
  require_same(ref, scheduled(b, 0.0, 5e-3, 1.0, false, pc));
  bool fast_hit = false;
  for (const auto& ev : ref.events) fast_hit = fast_hit || ev.particle == 1 || ev.other == 1;
  CHECK(fast_hit);
}

namespace {

/// One step of the crowd's own motion after the pair contacts: each velocity changed by its
/// particle's changes, a drift of dt, reflection at the walls of [0, side]^2 (a dense crowd
/// over many steps).
void drift(Balls& b, const PairContacts& pc, double dt, double side) {
  for (std::size_t i = 0; i < b.n(); ++i) {
    if (b.w[i] == 0.0) continue;
    for (const auto& c : pc.changes(i)) {
      b.v[2 * i] += c.dv.x();
      b.v[2 * i + 1] += c.dv.y();
    }
    for (int d = 0; d < 2; ++d) {
      double& x = b.x[2 * i + d];
      x += dt * b.v[2 * i + d];
      if ((x < 0.0 && b.v[2 * i + d] < 0.0) || (x > side && b.v[2 * i + d] > 0.0))
        b.v[2 * i + d] = -b.v[2 * i + d];
    }
  }
}

}  // namespace

TEST_CASE(
    "pair contacts: the list of nearby pairs kept over steps finds what the all-pairs loop finds") {
  // 1500 balls in a 0.4 square moving up to 1 m/s, 80 steps of 1 ms (1 mm of travel per step
  // against radii of 4-12 mm): the list lasts a few steps at a time. Between steps the state
  // is also changed the ways a scene can: a particle jumps across the square, one grows, one
  // is pinned and a pinned one freed, one's position is NaN for a step, a particle is added.
  // Every step must equal the all-pairs loop to the bit, kept list or new.
  const double side = 0.4, dt = 1e-3, e = 0.5;
  Balls b = crowd(1500, side, 21);
  PairContacts pc;
  std::size_t kept = 0, moved = 0, built = 0;
  for (int step = 0; step < 80; ++step) {
    std::optional<pinsim::test::FpTrapsOff> traps;  // step 40: comparisons with a NaN
    if (step == 40) traps.emplace();
    bool changed = true;
    if (step == 20) {
      b.x[2 * 5] = std::fmod(b.x[2 * 5] + 0.5 * side, side);
    } else if (step == 30) {
      b.r[7] *= 2.0;
    } else if (step == 35) {
      b.w[9] = 0.0;
      b.w[17] = 2.0;
    } else if (step == 40) {
      b.x[2 * 11] = std::nan("");
    } else if (step == 41) {
      b.x[2 * 11] = 0.5 * side;
    } else if (step == 50) {
      b.x.insert(b.x.end(), {0.5 * side, 0.5 * side});
      b.v.insert(b.v.end(), {0.3, -0.2});
      b.w.push_back(1.0);
      b.r.push_back(0.01);
    } else {
      changed = false;
    }
    const double t0 = step * dt;
    const Result ref = reference(b, t0, dt, e);
    const Result got = scheduled(b, t0, dt, e, false, pc);
    INFO("step " << step);
    require_same(ref, got);
    // a jump out of the list's reach, growth, a NaN: a new box in the list (or a new list);
    // a new particle count: a new list
    const PairContacts::Counts& n = pc.counts();
    if (changed && step != 35) CHECK((n.rebuilt || n.moved > 0));  // (pinning: still inside)
    if (step == 50) CHECK(n.rebuilt);
    built += n.rebuilt;
    moved += n.moved > 0;
    kept += !n.rebuilt && n.moved == 0;
    CHECK(n.listed >= n.candidates);
    drift(b, pc, dt, side);
  }
  CHECK(kept > 20);   // the list is kept as it is,
  CHECK(moved > 10);  // with a few new boxes in place,
  CHECK(built >= 2);  // or built anew
  INFO("kept " << kept << ", moved " << moved << ", built " << built);
}

TEST_CASE("pair contacts: pairs that meet at the very end of the step are found") {
  // Head-on pairs closing at 2 mm/s over gaps of 2 um (1 + k 1e-5), k = -20..20: times of
  // impact dt (1 + k 1e-5), a slow approach where the bound that rules pairs out before their
  // root (c + 2 b dt > 1e-6 (c - 2 b dt); its slack here is a tau^2 / (4 |b| dt), 2.5e-5)
  // must keep every pair that meets within the step, and the root decide.
  const double dt = 1e-3;
  Balls b;
  for (int k = -20; k <= 20; ++k) {
    const double y = 0.1 * (k + 20);
    const double gap = 2e-6 * (1.0 + k * 1e-5);
    b.x.insert(b.x.end(), {0.0, y, 0.02 + gap, y});
    b.v.insert(b.v.end(), {1e-3, 0.0, -1e-3, 0.0});
    b.w.insert(b.w.end(), {1.0, 1.0});
    b.r.insert(b.r.end(), {0.01, 0.01});
  }
  const Result ref = reference(b, 0.0, dt, 1.0);
  CHECK(ref.events.size() >= 20);  // k <= 0 (k = 0 to rounding)
  CHECK(ref.events.size() <= 21);
  PairContacts pc;
  require_same(ref, scheduled(b, 0.0, dt, 1.0, false, pc));
}

TEST_CASE("pair contacts: a particle that leaves its listed box on any one side is seen") {
  // Two balls far apart (not listed); then one is put against the other, approaching, so
  // that its swept box leaves its box of the list on the side facing the other only. The new
  // step must give it a new box in the list and find the hit, for each of the four sides.
  const double dt = 1e-3;
  for (const Vec2& dir : {Vec2(1.0, 0.0), Vec2(-1.0, 0.0), Vec2(0.0, 1.0), Vec2(0.0, -1.0)}) {
    INFO("direction " << dir.transpose());
    Balls b;
    b.x = {0.0, 0.0, 0.1 * dir.x(), 0.1 * dir.y()};
    b.v = {0.0, 0.0, 0.0, 0.0};
    b.w = {1.0, 1.0};
    b.r = {0.01, 0.01};
    PairContacts pc;
    require_same(reference(b, 0.0, dt, 1.0), scheduled(b, 0.0, dt, 1.0, false, pc));
    CHECK(pc.counts().listed == 0);
    b.x[2] = 0.0199 * dir.x();
    b.x[3] = 0.0199 * dir.y();
    b.v[2] = -0.1 * dir.x();
    b.v[3] = -0.1 * dir.y();
    const Result ref = reference(b, dt, dt, 1.0);
    REQUIRE(ref.events.size() == 1);
    require_same(ref, scheduled(b, dt, dt, 1.0, false, pc));
    CHECK(pc.counts().moved == 1);
  }
}

TEST_CASE("pair contacts: two particles that leave their boxes in one step meet once") {
  // Three balls at rest far apart (none listed); then two are put against each other,
  // approaching, and the third moves beside them: all leave their listed boxes in the same
  // step and get new ones in place. The pair of the two must be listed once (one candidate,
  // one hit), as the all-pairs loop sees it; and again a step later, when one of them has
  // moved before and the other leaves again.
  const double dt = 1e-3;
  Balls b;
  b.x = {0.0, 0.0, 0.3, 0.0, 0.0, 0.3};
  b.v = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  b.w = {1.0, 1.0, 1.0};
  b.r = {0.01, 0.01, 0.01};
  PairContacts pc;
  require_same(reference(b, 0.0, dt, 1.0), scheduled(b, 0.0, dt, 1.0, false, pc));
  REQUIRE(pc.counts().listed == 0);
  b.x = {0.1, 0.0, 0.1201, 0.0, 0.1, 0.05};
  b.v = {0.1, 0.0, -0.1, 0.0, 0.0, -0.1};
  Result ref = reference(b, dt, dt, 1.0);
  REQUIRE(ref.candidates == 1);
  REQUIRE(ref.events.size() == 1);
  require_same(ref, scheduled(b, dt, dt, 1.0, false, pc));
  CHECK(pc.counts().moved == 3);
  CHECK(!pc.counts().rebuilt);
  // ball 1 leaves again toward ball 0 (moved before, now in place): one pair again
  b.x = {0.1, 0.0, 0.1201, 0.0, 0.1, 0.05};
  b.v = {0.0, 0.0, -5.0, 0.0, 0.0, 0.0};
  ref = reference(b, 2 * dt, dt, 1.0);
  REQUIRE(ref.candidates == 1);
  require_same(ref, scheduled(b, 2 * dt, dt, 1.0, false, pc));
  CHECK(pc.counts().moved == 1);
  CHECK(!pc.counts().rebuilt);
}

TEST_CASE("pair contacts: a leaver among listed neighbours keeps each pair once") {
  // A touching row of balls at rest, listed in one build; then ball 5 (or the first or the
  // last) is kicked up so that its swept box leaves its list box: its listed pairs with its
  // neighbours (in its own run and in the run of the lower one) must be retired and found
  // again from the build's grid with its new box, each once, and the step equal the
  // all-pairs loop; and two steps later a neighbour leaves too.
  for (const std::size_t kicked : {std::size_t{0}, std::size_t{5}, std::size_t{11}}) {
    INFO("kicked ball " << kicked);
    const double dt = 1e-3;
    Balls b;
    for (int k = 0; k < 12; ++k) {
      b.x.insert(b.x.end(), {0.02 * k, 0.0});
      b.v.insert(b.v.end(), {0.0, 0.0});
      b.w.push_back(1.0);
      b.r.push_back(0.01);
    }
    PairContacts pc;
    require_same(reference(b, 0.0, dt, 0.5), scheduled(b, 0.0, dt, 0.5, false, pc));
    REQUIRE(pc.counts().listed == 11);
    b.v[2 * kicked + 1] = 5.0;  // 5 mm up in the step: beyond its box (skin 2.5 mm)
    for (int step = 1; step < 4; ++step) {
      if (step == 3) b.v[2 * (kicked == 11 ? 10 : kicked + 1)] = -3.0;  // a neighbour leaves
      const Result ref = reference(b, step * dt, dt, 0.5);
      CHECK(ref.candidates >= 1);
      require_same(ref, scheduled(b, step * dt, dt, 0.5, false, pc));
      CHECK(!pc.counts().rebuilt);
      if (step == 1) CHECK(pc.counts().moved == 1);
      for (std::size_t i = 0; i < b.n(); ++i) {  // move on
        b.x[2 * i] += dt * b.v[2 * i];
        b.x[2 * i + 1] += dt * b.v[2 * i + 1];
      }
    }
  }
}

TEST_CASE("pair contacts: a list kept for 128 steps is built anew, with the same hits") {
  // Balls at rest in a touching row, pushed together every step: nothing leaves its box,
  // so the list would be kept for ever; after 128 steps it is built anew all the same (boxes
  // grown for an earlier motion must not stay), and every step equals the all-pairs loop.
  Balls b;
  for (int k = 0; k < 40; ++k) {
    b.x.insert(b.x.end(), {0.02 * k, 0.0});
    b.v.insert(b.v.end(), {k % 2 == 0 ? 0.01 : -0.01, 0.0});
    b.w.push_back(1.0);
    b.r.push_back(0.01);
  }
  PairContacts pc;
  std::vector<int> builds;
  for (int step = 0; step < 300; ++step) {
    const Result ref = reference(b, step * 1e-3, 1e-3, 0.0);
    require_same(ref, scheduled(b, step * 1e-3, 1e-3, 0.0, false, pc));
    if (pc.counts().rebuilt) builds.push_back(step);
  }
  CHECK(builds == std::vector<int>{0, 129, 258});
}
