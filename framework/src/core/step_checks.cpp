#include "core/step_checks.hpp"

#include <algorithm>
#include <pinsim/parallel.hpp>

namespace pinsim {

void StepChecks::start(const State& s, double scale0, double growth) {
  growth_ = growth;
  scale_ = scale0;
  steps_ = 0;
  drifted_ = false;
  const Eigen::Index n = s.x.cols();
  half_mass_.resize(n);
  k_.resize(n);
  k_next_.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    half_mass_[i] = s.inv_mass[i] > 0.0 ? 0.5 / s.inv_mass[i] : 0.0;
    k_[i] = half_mass_[i] * s.v.col(i).squaredNorm();
  }
  v_in_ = s.v;
  v_out_ = s.v;
}

// Why legitimate steps stay inside the bound K_i^free <= G (K_i^n + S_n).
// With h = dt and a_i = f_i / m_i, the forces change v_i over a step by dv_i = v_i^free - v_i^n:
// the Euler methods and velocity Verlet by kicks whose weights sum to h, RK4 by h times a
// weighted mean of its stage accelerations, implicit Euler by h times the acceleration at
// the linearised end state; Verlet and RK4 add an impact correction of at most (1 + e) h |a_i|.
// So |dv_i| is a few h |a_i|, and
//   K_i^free = m_i |v_i^n + dv_i|^2 / 2 <= 2 K_i^n + 2 W_i,   W_i = m_i |dv_i|^2 / 2,
// W_i being what the step's forces alone would give the particle from rest.
// - A force that changes little over a step (gravity; a particle resting on a floor, or
//   starting from rest) gives about the same W_i every step, and the previous step's total
//   K^free, part of S_n, already holds it (a resting particle has K^n ~ 0 and K^free ~ W_i).
//   Free fall from rest is the extreme case: K^free / K^n = ((n + 1) / n)^2 <= 4 from the
//   second step on.
// - A spring of stiffness k stretched by d on a particle of mass m: W = (h w)^2 U with
//   w^2 = k / m and U = k d^2 / 2. The explicit methods are stable only for (h w)^2 <= 4 (RK4
//   8), and U came from the scene's energy, which S_n holds (the initial energy scale, or the
//   kinetic energy it was turned from), so W <= 8 S_n per force at its stability limit.
// G = 32 thus leaves room for a particle pulled by two stiff forces at their limits, or an
// impact correction on top of a kick. Free fall from rest and springs released at the
// stability limits of symplectic Euler and RK4 pass even at G = 2
// (tests/framework/core/test_numeric_checks.cpp).
// Energy fed in from outside arrives through contacts (a plunger or a flipper striking, a
// bumper's kick) and is not bounded here: the backend's change of velocity during its drift
// is taken out of K^free, and what it adds is in K^{n+1} and S_{n+1}, so the next steps
// start from it; the total-energy check (checks.energy_blowup) covers it.
// The first step is not checked: S_0 is the initial energy scale alone, which depends on
// where each potential is zero (gravity's m g y), and a particle falling from rest at y = 0
// has S_0 = 0 < K^free.
// What the bound catches: an instability multiplies a particle's energy by lambda^2 per step.
// Once that particle holds most of the kinetic energy (K_i^n ~ S_n) the bound is 2 G K_i^n,
// so growth faster than 2 G = 64 per step stops at its second step. Symplectic Euler on a
// spring has lambda + 1/lambda = (h w)^2 - 2: lambda^2 > 64 for h w > 3.18. Slower growth
// is left to the total-energy check.
StepFinding StepChecks::check(const State& s) {
  if (!drifted_) {  // a check without a drift around it: no contact velocity to take out
    v_in_ = s.v;
    v_out_ = s.v;
  }
  drifted_ = false;
  // after_last_drift: the velocities leaving the drift are s.v (the same values a copy
  // would hold); the findings below read v_out_, filled only then
  const bool out_is_v = out_is_v_;
  out_is_v_ = false;
  auto finding = [&](StepFinding (StepChecks::*what)(const State&) const) {
    if (out_is_v) v_out_ = s.v;
    return (this->*what)(s);
  };
  const Eigen::Index n = s.x.cols();
  const double* x = s.x.data();
  const double* v = s.v.data();
  const double* vin = v_in_.data();
  const double* vout = out_is_v ? v : v_out_.data();
  const double* hm = half_mass_.data();
  const double* kp = k_.data();
  double* kn = k_next_.data();
  // 0 * y is 0 for finite y and NaN for an infinity or a NaN, so the sum is NaN exactly when
  // some coordinate is not finite (one pass, no branch). The particles run in fixed chunks
  // (pinsim/parallel.hpp), each summing into its own slot; the slots are then combined in
  // chunk order, so the sums do not depend on the thread count (with one chunk, up to
  // kParticleChunk particles, they are the plain serial sums; below kParallelItems the chunks
  // run in order on this thread).
  const auto total = static_cast<std::size_t>(n);
  // sum(b, e) over the particles [b, e), all the chunks' sums added in chunk order
  auto chunked = [&](auto&& sum) {
    if (total <= kParticleChunk) return sum(std::size_t{0}, total);  // the serial loop
    parts_.assign(chunk_count(total, kParticleChunk), Part{});
    for_chunks(
        total, kParticleChunk,
        [&](std::size_t c, std::size_t b, std::size_t e) { parts_[c] = sum(b, e); },
        Schedule::Even);
    Part all;
    for (const Part& p : parts_) {
      all.poison += p.poison;
      all.over |= p.over;
      all.k_sum += p.k_sum;
      all.kf_sum += p.kf_sum;
    }
    return all;
  };
  if (growth_ > 0.0) {
    const double g = growth_, gs = growth_ * scale_;
    const Part all = chunked([&](std::size_t b, std::size_t e) {
      Part p;
      for (std::size_t i = b; i < e; ++i) {
        const double vx = v[2 * i], vy = v[2 * i + 1];
        p.poison += 0.0 * x[2 * i] + 0.0 * x[2 * i + 1] + 0.0 * vx + 0.0 * vy;
        const double fx = vx - (vout[2 * i] - vin[2 * i]),
                     fy = vy - (vout[2 * i + 1] - vin[2 * i + 1]);
        const double k = hm[i] * (vx * vx + vy * vy), kf = hm[i] * (fx * fx + fy * fy);
        p.over |= static_cast<int>(kf > g * kp[i] + gs);
        p.k_sum += k;
        p.kf_sum += kf;
        kn[i] = k;
      }
      return p;
    });
    if (!(all.poison == 0.0)) return finding(&StepChecks::non_finite);
    if (all.over != 0 && steps_ > 0) return finding(&StepChecks::growth);
    scale_ = std::max({scale_, all.k_sum, all.kf_sum});
    k_.swap(k_next_);
  } else {
    const Part all = chunked([&](std::size_t b, std::size_t e) {
      Part p;
      for (std::size_t i = 2 * b; i < 2 * e; ++i) p.poison += 0.0 * x[i] + 0.0 * v[i];
      return p;
    });
    if (!(all.poison == 0.0)) return finding(&StepChecks::non_finite);
  }
  ++steps_;
  return {};
}

void StepChecks::copy_chunks(const Eigen::Matrix2Xd& from, Eigen::Matrix2Xd& to) {
  to.resize(2, from.cols());
  for_chunks(
      static_cast<std::size_t>(from.cols()), kParticleChunk,
      [&](std::size_t, std::size_t b, std::size_t e) {
        const auto i = static_cast<Eigen::Index>(b), k = static_cast<Eigen::Index>(e - b);
        to.middleCols(i, k) = from.middleCols(i, k);
      },
      Schedule::Even);
}

namespace {
bool finite(const Eigen::Vector2d& a) { return a.allFinite(); }
/// The first particle of s with a non-finite position or velocity, or -1.
Eigen::Index first_non_finite(const State& s) {
  for (Eigen::Index i = 0; i < s.x.cols(); ++i)
    if (!s.x.col(i).allFinite() || !s.v.col(i).allFinite()) return i;
  return -1;
}
}  // namespace

StepFinding StepChecks::after_substep_drift(const State& s) {
  drift_change_ += s.v - v_sub_;
  if (s.x.allFinite() && s.v.allFinite()) return {};
  StepFinding f;
  f.what = StepFinding::What::NonFinite;
  f.v_in.setZero();
  if (const Eigen::Index i = first_non_finite(s); i >= 0) {
    f.particle = i;
    f.v_in = v_sub_.col(i);
    f.phase = finite(f.v_in) ? StepFinding::Phase::Drift : StepFinding::Phase::BeforeDrift;
  }
  return f;
}

StepFinding StepChecks::non_finite(const State& s) const {
  StepFinding f;
  f.what = StepFinding::What::NonFinite;
  f.v_in.setZero();
  if (const Eigen::Index i = first_non_finite(s); i >= 0) {
    f.particle = i;
    f.v_in = v_in_.col(i);
    // x changes only in the drift; v by the forces before it, the backend in it, and the
    // forces after it (Verlet's closing half kick, explicit Euler's kick).
    if (!finite(f.v_in))
      f.phase = StepFinding::Phase::BeforeDrift;
    else if (!s.x.col(i).allFinite() || !finite(v_out_.col(i)))
      f.phase = StepFinding::Phase::Drift;
    else
      f.phase = StepFinding::Phase::AfterDrift;
  }
  return f;
}

StepFinding StepChecks::growth(const State& s) const {
  // The particle whose kinetic energy grew most among those past the bound.
  StepFinding f;
  f.what = StepFinding::What::Growth;
  f.scale = scale_;
  double most = -1.0;
  for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
    const Eigen::Vector2d vf = s.v.col(i) - (v_out_.col(i) - v_in_.col(i));
    const double kf = half_mass_[i] * vf.squaredNorm();
    if (!(kf > growth_ * (k_[i] + scale_))) continue;
    if (kf - k_[i] > most) {
      most = kf - k_[i];
      f.particle = i;
      f.k_prev = k_[i];
      f.k_free = kf;
      f.v_in = v_in_.col(i);
    }
  }
  return f;
}

}  // namespace pinsim
