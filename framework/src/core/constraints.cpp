#include "core/constraints.hpp"

#include <cmath>
#include <string>

namespace pinsim {
namespace {

bool valid_coefficient(double k) { return k >= 0.0 && !std::isnan(k); }

}  // namespace

ConstraintSystem ConstraintSystem::gather(const std::vector<std::unique_ptr<ForceInstance>>& forces,
                                          const std::vector<std::string>& labels,
                                          std::size_t n_particles) {
  ConstraintSystem out;
  out.covers_.assign(forces.size(), 0);
  out.start_.push_back(0);
  for (std::size_t k = 0; k < forces.size(); ++k) {
    const ForceInstance& f = *forces[k];
    out.forces_.push_back(&f);
    if (!f.provides_constraints()) continue;
    out.covers_[k] = 1;
    const pinsim_constraint_set set = f.constraint_set();
    const std::string& who = labels[k];
    auto bad = [&](const std::string& what) {
      throw PluginError(who + ": its constraint set " + what);
    };
    if (set.count > 0 && (set.particles == nullptr || set.ks == nullptr || set.kd == nullptr))
      bad("has " + std::to_string(set.count) + " constraints but a NULL array");
    if (set.arity != PINSIM_ARITY_VARIABLE && set.arity > 4096)
      bad("declares arity " + std::to_string(set.arity));
    if (set.count > (uint64_t{1} << 31)) bad("has " + std::to_string(set.count) + " constraints");
    const uint32_t* p = set.particles;
    for (uint64_t e = 0; e < set.count; ++e) {
      uint32_t len = set.arity;
      if (set.arity == PINSIM_ARITY_VARIABLE) {
        len = *p++;
        if (len == 0 || len > n_particles)
          bad("gives constraint " + std::to_string(e) + " " + std::to_string(len) + " particles");
      }
      for (uint32_t a = 0; a < len; ++a, ++p) {
        if (*p >= n_particles)
          bad("gives constraint " + std::to_string(e) + " particle " + std::to_string(*p) +
              ", outside the state (" + std::to_string(n_particles) + " particles)");
        out.particles_.push_back(*p);
      }
      if (!valid_coefficient(set.ks[e]) || !valid_coefficient(set.kd[e]))
        bad("gives constraint " + std::to_string(e) + " ks = " + std::to_string(set.ks[e]) +
            ", kd = " + std::to_string(set.kd[e]) + " (both must be >= 0)");
      out.start_.push_back(out.particles_.size());
      out.force_.push_back(static_cast<uint32_t>(k));
      out.element_.push_back(e);
      out.ks_.push_back(set.ks[e]);
      out.kd_.push_back(set.kd[e]);
    }
  }
  return out;
}

void ConstraintSystem::evaluate(const double* x, const uint32_t* ids, const uint64_t* elements,
                                std::size_t n, double* c, double* dc) const {
  std::size_t k = 0;
  while (k < n) {
    // the run of consecutive ids of one force: one call
    const uint32_t f = force_[ids[k]];
    std::size_t end = k + 1, slots = start_[ids[k] + 1] - start_[ids[k]];
    while (end < n && force_[ids[end]] == f) {
      slots += start_[ids[end] + 1] - start_[ids[end]];
      ++end;
    }
    forces_[f]->constraints(x, elements + k, end - k, c + k, dc);
    dc += 2 * slots;
    k = end;
  }
}

}  // namespace pinsim
