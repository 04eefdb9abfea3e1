#include "core/xpbd_constraints.hpp"

#include <algorithm>
#include <cmath>

namespace pinsim {

XpbdConstraints::XpbdConstraints(const ConstraintSystem& system, const std::vector<char>& include,
                                 const std::vector<char>& moves, const Eigen::VectorXd& inv_mass)
    : system_(&system), colouring_(colour_constraints(system, include, moves)) {
  ids_ = colouring_.order;
  slot_.assign(1, 0);
  for (std::size_t q = 0; q < ids_.size(); ++q) {
    const uint32_t j = ids_[q];
    elements_.push_back(system.element(j));
    for (uint32_t i : system.particles(j)) {
      particles_.push_back(i);
      w_.push_back(inv_mass[static_cast<Eigen::Index>(i)]);
    }
    slot_.push_back(particles_.size());
    ks_.push_back(system.ks(j));
    kd_.push_back(system.kd(j));
    const auto m = static_cast<uint32_t>(system.particles(j).size());
    arity_ = q == 0 || arity_ == m ? m : 0;
  }
  run_end_.resize(ids_.size());
  for (std::size_t q = ids_.size(); q-- > 0;)
    run_end_[q] = q + 1 < ids_.size() && system.force(ids_[q + 1]) == system.force(ids_[q])
                      ? run_end_[q + 1]
                      : q + 1;
  lambda_.assign(ids_.size(), 0.0);
  dl_.assign(ids_.size(), 0.0);
  c_.assign(ids_.size(), 0.0);
  dc_.assign(2 * particles_.size(), 0.0);
  at_.assign(ids_.size(), 0.0);
  gamma_.assign(ids_.size(), 0.0);
}

void XpbdConstraints::set_step(double h) {
  if (h == h_) return;
  h_ = h;
  for (std::size_t q = 0; q < ids_.size(); ++q) {
    // alpha~ = alpha / h^2 with alpha = 1 / ks (0 for an infinitely stiff constraint);
    // gamma = alpha~ beta h with beta = kd (eq. 26); neither is used for a damper (ks = 0)
    if (!(ks_[q] > 0.0)) continue;
    at_[q] = 1.0 / (ks_[q] * h * h);
    gamma_[q] = kd_[q] == 0.0 ? 0.0 : at_[q] * kd_[q] * h;
  }
}

void XpbdConstraints::evaluate(const double* x, std::size_t b, std::size_t e) {
  // one call per run of positions of one force
  for (std::size_t q = b; q < e;) {
    const std::size_t end = std::min(run_end_[q], e);
    system_->evaluate_force(system_->force(ids_[q]), x, elements_.data() + q, end - q,
                            c_.data() + q, dc_.data() + 2 * slot_[q]);
    q = end;
  }
}

std::size_t XpbdConstraints::project(const double* x, double* p, bool first_sweep, bool keep_lambda,
                                     std::size_t b, std::size_t e) {
  if (b == e) return kFine;
  evaluate(p, b, e);
  switch (arity_) {
    case 2:
      return project_arity<2>(x, p, first_sweep, keep_lambda, b, e);
    case 3:
      return project_arity<3>(x, p, first_sweep, keep_lambda, b, e);
    default:
      return project_arity<0>(x, p, first_sweep, keep_lambda, b, e);
  }
}

// M > 0: every constraint has M particles (slot q = M q); M = 0: any number, from slot_.
// The constraints of one colour share no moving particle, so each reads only the positions of
// its own particles, which no other constraint of [b, e) writes: all the dlambda first (their
// divisions independent of one another), then all the updates, give the same bits as one
// constraint after the other. Plain pointers: through the members the compiler would reload
// them after every store to p.
template <uint32_t M>
std::size_t XpbdConstraints::project_arity(const double* x, double* p, bool first_sweep,
                                           bool keep_lambda, std::size_t b, std::size_t e) {
  const std::size_t* slot = slot_.data();
  const uint32_t* particles = particles_.data();
  const double* w = w_.data();
  const double* dc = dc_.data();
  const double* c = c_.data();
  const double* at = at_.data();
  const double* gm = gamma_.data();
  double* lambda = lambda_.data();
  double* dls = dl_.data() + b;  // dlambda of position q at dls[q - b]
  for (std::size_t q = b; q < e; ++q) {
    const std::size_t s0 = M > 0 ? M * q : slot[q];
    const std::size_t m = M > 0 ? M : slot[q + 1] - s0;
    const double* g = dc + 2 * s0;
    const uint32_t* id = particles + s0;
    const double* wq = w + s0;
    double sw = 0.0;
    for (std::size_t a = 0; a < m; ++a)
      sw += wq[a] * (g[2 * a] * g[2 * a] + g[2 * a + 1] * g[2 * a + 1]);
    const double gamma = gm[q];
    double gdx = 0.0;  // J (p - x), needed only with damping
    if (gamma != 0.0)
      for (std::size_t a = 0; a < m; ++a) {
        const uint32_t i = id[a];
        gdx += g[2 * a] * (p[2 * i] - x[2 * i]) + g[2 * a + 1] * (p[2 * i + 1] - x[2 * i + 1]);
      }
    const double denom = (1.0 + gamma) * sw + at[q];
    // denom = 0: no moving particle, or a zero gradient, with alpha~ = 0: no update
    const double l = first_sweep ? 0.0 : lambda[q];
    const double dl = denom == 0.0 ? 0.0 : (-c[q] - at[q] * l - gamma * gdx) / denom;
    dls[q - b] = dl;
    if (keep_lambda) lambda[q] = l + dl;
  }
  // 0 y is 0 for a finite y and NaN otherwise: poison != 0 when a write was not finite
  double poison = 0.0;
  for (std::size_t q = b; q < e; ++q) {
    const std::size_t s0 = M > 0 ? M * q : slot[q];
    const std::size_t m = M > 0 ? M : slot[q + 1] - s0;
    const double* g = dc + 2 * s0;
    const uint32_t* id = particles + s0;
    const double* wq = w + s0;
    const double dl = dls[q - b];
    for (std::size_t a = 0; a < m; ++a) {
      if (!(wq[a] > 0.0)) continue;  // pinned: never written (other colours share it)
      const uint32_t i = id[a];
      const double px = p[2 * i] + wq[a] * dl * g[2 * a];
      const double py = p[2 * i + 1] + wq[a] * dl * g[2 * a + 1];
      p[2 * i] = px;
      p[2 * i + 1] = py;
      poison += 0.0 * px + 0.0 * py;
    }
  }
  return poison == 0.0 ? kFine : first_non_finite(p, b, e);
}

std::size_t XpbdConstraints::first_non_finite(const double* out, std::size_t b,
                                              std::size_t e) const {
  for (std::size_t q = b; q < e; ++q)
    for (std::size_t k = slot_[q]; k < slot_[q + 1]; ++k) {
      const uint32_t i = particles_[k];
      if (w_[k] > 0.0 && !(std::isfinite(out[2 * i]) && std::isfinite(out[2 * i + 1]))) return q;
    }
  return kFine;  // not reached: the caller saw a non-finite write
}

std::size_t XpbdConstraints::damp(const double* x, double* v, std::size_t b, std::size_t e) {
  if (b == e) return kFine;
  evaluate(x, b, e);
  double poison = 0.0;  // as in project_arity
  for (std::size_t q = b; q < e; ++q) {
    const std::size_t s0 = slot_[q], m = slot_[q + 1] - s0;
    const double* g = dc_.data() + 2 * s0;
    const uint32_t* id = particles_.data() + s0;
    const double* wq = w_.data() + s0;
    // v' = v - h kd M^-1 J^T (J v') gives J v' = J v / (1 + h kd W), W = sum_i w_i |J_i|^2
    double sw = 0.0, jv = 0.0;
    for (std::size_t a = 0; a < m; ++a) {
      const uint32_t i = id[a];
      sw += wq[a] * (g[2 * a] * g[2 * a] + g[2 * a + 1] * g[2 * a + 1]);
      jv += g[2 * a] * v[2 * i] + g[2 * a + 1] * v[2 * i + 1];
    }
    if (sw == 0.0) continue;  // no moving particle, or a zero gradient
    const double hkd = h_ * kd_[q];
    const double dv = -hkd * jv / (1.0 + hkd * sw);
    for (std::size_t a = 0; a < m; ++a) {
      if (!(wq[a] > 0.0)) continue;
      const uint32_t i = id[a];
      const double vx = v[2 * i] + wq[a] * dv * g[2 * a];
      const double vy = v[2 * i + 1] + wq[a] * dv * g[2 * a + 1];
      v[2 * i] = vx;
      v[2 * i + 1] = vy;
      poison += 0.0 * vx + 0.0 * vy;
    }
  }
  return poison == 0.0 ? kFine : first_non_finite(v, b, e);
}

}  // namespace pinsim
