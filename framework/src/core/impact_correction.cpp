#include <algorithm>

#include "core/integrators.hpp"

namespace pinsim {

void correct_impacts(State& s, std::span<const pinsim_event> contacts, double t0,
                     const ImpactReference& ref) {
  if (ref.a_n == nullptr) return;
  const Eigen::Matrix2Xd& a_n = *ref.a_n;
  const double c_h = ref.c_h;
  for (const pinsim_event& e : contacts) {
    if (e.obstacle < 0 || e.particle < 0 || !(e.vn_before < 0.0)) continue;
    const auto i = static_cast<Eigen::Index>(e.particle);
    if (i >= s.v.cols() || !(s.inv_mass[i] > 0.0)) continue;
    const Eigen::Vector2d n(e.normal[0], e.normal[1]);
    // 1 + e from the normal velocities the backend reports, kept in [1, 2].
    const double one_e = std::clamp((e.vn_after - e.vn_before) / -e.vn_before, 1.0, 2.0);
    const double tau = e.t - t0;
    const double dvn = (tau - c_h) * a_n.col(i).dot(n);
    s.v.col(i) -= one_e * dvn * n;
  }
}

}  // namespace pinsim
