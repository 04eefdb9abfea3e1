// The pair contacts' first test of a listed pair (pair_list.cpp, scan_list): whether two
// particles' boxes swept over the step overlap, and whether the pair may meet within it.
// Written twice with the same arithmetic: on doubles one by one, and on SSE2's pairs of
// doubles (x and y side by side) where the target has them; both give the same answers
// (tests/backends/sdf/test_pair_look.cpp compares them).
#pragma once

#include <algorithm>

#if defined(__SSE2__)
#include <emmintrin.h>
#define PINSIM_PAIR_LOOK_PACKED 1
#endif

namespace pinsim::sdf {

/// A particle at the start of the step: position, velocity (0 if pinned), radius, inverse
/// mass.
struct PairStart {
  double x, y, vx, vy, r, w;
};

/// The box a particle sweeps over a step, grown by its radius.
struct SweptBox {
  double x0, x1, y0, y1;
};

/// The box PairStart p sweeps over dt, grown by its radius.
inline SweptBox swept_box(const PairStart& p, double dt) {
  const double px = p.x + dt * p.vx, py = p.y + dt * p.vy;
  return {std::min(p.x, px) - p.r, std::max(p.x, px) + p.r, std::min(p.y, py) - p.r,
          std::max(p.y, py) + p.r};
}

/// What the scan's test computes of a pair (P, Q): whether it is a candidate (closed swept
/// boxes that overlap, not both pinned), b = dx.dv and c = dx.dx - (r_P + r_Q)^2.
struct PairFigures {
  unsigned candidate;
  double b, c;
};

/// The pair's figures on doubles one by one. For particles with finite swept boxes.
[[gnu::always_inline]] inline PairFigures figures_scalar(const PairStart& P, const PairStart& Q,
                                                         double dt) {
  const SweptBox A = swept_box(P, dt), B = swept_box(Q, dt);
  const unsigned candidate =
      static_cast<unsigned>(A.x0 <= B.x1) & static_cast<unsigned>(B.x0 <= A.x1) &
      static_cast<unsigned>(A.y0 <= B.y1) & static_cast<unsigned>(B.y0 <= A.y1) &
      static_cast<unsigned>(P.w != 0.0 || Q.w != 0.0);
  const double dx = P.x - Q.x, dy = P.y - Q.y, dvx = P.vx - Q.vx, dvy = P.vy - Q.vy;
  const double rr = P.r + Q.r;
  return {candidate, dx * dvx + dy * dvy, (dx * dx + dy * dy) - rr * rr};
}

#if PINSIM_PAIR_LOOK_PACKED
/// figures_scalar on pairs of doubles: the same operations on each coordinate (a product or
/// a sum of two doubles is one rounding either way; minpd and maxpd with their operands
/// swapped pick what std::min and std::max pick, ties and NaN included).
[[gnu::always_inline]] inline PairFigures figures_packed(const PairStart& P, const PairStart& Q,
                                                         double dt) {
  const __m128d vdt = _mm_set1_pd(dt);
  const __m128d px = _mm_loadu_pd(&P.x), pv = _mm_loadu_pd(&P.vx);
  const __m128d qx = _mm_loadu_pd(&Q.x), qv = _mm_loadu_pd(&Q.vx);
  const __m128d pr = _mm_set1_pd(P.r), qr = _mm_set1_pd(Q.r);
  const __m128d pe = _mm_add_pd(px, _mm_mul_pd(vdt, pv)), qe = _mm_add_pd(qx, _mm_mul_pd(vdt, qv));
  const __m128d alo = _mm_sub_pd(_mm_min_pd(pe, px), pr), ahi = _mm_add_pd(_mm_max_pd(pe, px), pr);
  const __m128d blo = _mm_sub_pd(_mm_min_pd(qe, qx), qr), bhi = _mm_add_pd(_mm_max_pd(qe, qx), qr);
  const int overlap = _mm_movemask_pd(_mm_and_pd(_mm_cmple_pd(alo, bhi), _mm_cmple_pd(blo, ahi)));
  const __m128d d = _mm_sub_pd(px, qx), dv = _mm_sub_pd(pv, qv);
  const __m128d b2 = _mm_mul_pd(d, dv), c2 = _mm_mul_pd(d, d);
  const double rr = P.r + Q.r;
  return {static_cast<unsigned>(overlap == 3) & static_cast<unsigned>(P.w != 0.0 || Q.w != 0.0),
          _mm_cvtsd_f64(b2) + _mm_cvtsd_f64(_mm_unpackhi_pd(b2, b2)),
          (_mm_cvtsd_f64(c2) + _mm_cvtsd_f64(_mm_unpackhi_pd(c2, c2))) - rr * rr};
}
#endif

/// The scan's test of a listed pair (P, Q): whether it is a candidate (into candidate), and
/// whether it is one left for the root (returned): approaching (b < 0) and not ruled out by
/// the bound c + 2 b dt > 1e-6 (c - 2 b dt) when apart (pair_list.cpp gives the reasoning).
/// Packed where SSE2 is there, else one by one.
[[gnu::always_inline]] inline unsigned look(const PairStart& P, const PairStart& Q, double dt,
                                            unsigned& candidate) {
#if PINSIM_PAIR_LOOK_PACKED
  const PairFigures f = figures_packed(P, Q, dt);
#else
  const PairFigures f = figures_scalar(P, Q, dt);
#endif
  candidate = f.candidate;
  const double reach = 2.0 * f.b * dt;  // <= 0 when approaching
  const unsigned beyond =
      static_cast<unsigned>(f.c > 0.0) & static_cast<unsigned>(f.c + reach > 1e-6 * (f.c - reach));
  return f.candidate & static_cast<unsigned>(f.b < 0.0) & (beyond ^ 1u);
}

}  // namespace pinsim::sdf
