// The integrators behind make_integrator, one file each, and the helpers they share.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <pinsim/parallel.hpp>
#include <pinsim/state.hpp>
#include <span>
#include <vector>

#include "core/integrator.hpp"

namespace pinsim {

/// Calls body(begin, count) for fixed chunks of kParticleChunk of the particles [0, n), on
/// threads from kParallelItems particles (pinsim/parallel.hpp, Schedule::Even: one run of
/// chunks per thread). For per-particle updates that read and write only their own
/// particles: the bits do not depend on the chunks.
template <class Body>
void per_particle(Eigen::Index n, Body&& body) {
  for_chunks(
      static_cast<std::size_t>(n), kParticleChunk,
      [&](std::size_t, std::size_t b, std::size_t e) {
        body(static_cast<Eigen::Index>(b), static_cast<Eigen::Index>(e - b));
      },
      Schedule::Even);
}

/// a = M^-1 f per particle (pinned particles, inv_mass 0, get a = 0).
inline void accelerations(const State& s, const Eigen::Matrix2Xd& f, Eigen::Matrix2Xd& a) {
  a.resize(2, s.x.cols());
  per_particle(s.x.cols(), [&](Eigen::Index b, Eigen::Index n) {
    for (Eigen::Index i = b; i < b + n; ++i) a.col(i) = s.inv_mass[i] * f.col(i);
  });
}

/// The kick v += h M^-1 f per particle (pinned particles have inv_mass 0 and keep their
/// velocity); with `copy`, copy = the kicked velocities too (resized), in the same pass.
/// Through plain pointers: through the matrices' members the compiler reloads their data
/// pointers after every store.
inline void kick(State& s, const Eigen::Matrix2Xd& f, double h, Eigen::Matrix2Xd* copy = nullptr) {
  double* v = s.v.data();
  const double* fd = f.data();
  const double* w = s.inv_mass.data();
  double* out = nullptr;
  if (copy != nullptr) {
    copy->resize(2, s.v.cols());
    out = copy->data();
  }
  for_chunks(
      static_cast<std::size_t>(s.v.cols()), kParticleChunk,
      [=](std::size_t, std::size_t b, std::size_t e) {
        if (out == nullptr) {
          for (std::size_t i = b; i < e; ++i) {
            const double a = h * w[i];
            v[2 * i] += a * fd[2 * i];
            v[2 * i + 1] += a * fd[2 * i + 1];
          }
          return;
        }
        for (std::size_t i = b; i < e; ++i) {
          const double a = h * w[i];
          const double vx = v[2 * i] + a * fd[2 * i], vy = v[2 * i + 1] + a * fd[2 * i + 1];
          v[2 * i] = vx;
          v[2 * i + 1] = vy;
          out[2 * i] = vx;
          out[2 * i + 1] = vy;
        }
      },
      Schedule::Even);
}

/// The impact correction (impact_correction.cpp) of the obstacle contacts `contacts` of a
/// drift that started at t0 and moved every particle with the constant velocity
/// v_n + c h a_n (ref), when the particle's true velocity at the time of impact t0 + tau is
/// v_n + tau a_n (a_n = M^-1 f(x_n)). The backend reflected the normal velocity vn of the
/// drift velocity; the impulse it should have reflected is vn + (tau - c h) a_n.n, so each
/// contact adds
///   dv = -(1 + e) (tau - c h) (a_n.n) n,   1 + e = (vn_after - vn_before) / -vn_before.
/// Without it a bounce leaves an O(h) velocity error and a second-order method drops to
/// first order (see docs/bench_and_stress.md); with it the error per bounce is O(h^2).
/// Nothing when ref has no a_n.
void correct_impacts(State& s, std::span<const pinsim_event> contacts, double t0,
                     const ImpactReference& ref);

/// Symplectic Euler, kick then drift (integrator_euler.cpp).
std::unique_ptr<Integrator> make_symplectic_euler();
/// Velocity Verlet, kick/2 - drift - kick/2 (integrator_verlet.cpp).
std::unique_ptr<Integrator> make_velocity_verlet();
/// Forward (explicit) Euler: x_{n+1} = x_n + h v_n (the drift), v_{n+1} = v_n + h M^-1 f_n.
std::unique_ptr<Integrator> make_explicit_euler();
/// Classical fourth-order Runge-Kutta; the position update goes through the backend
/// (integrator_rk4.cpp).
std::unique_ptr<Integrator> make_rk4();
/// Settings of implicit Euler's linear solve (tests force a fallback with them).
struct ImplicitEulerOptions {
  long cg_max_iterations = 0;  ///< 0: max(100, 4 x dofs)
  /// Jacobian items (a 2x2 block or a single entry counts one) from which a concurrent force
  /// scatters into its own copy of A on a thread of its own (the first such force excepted); tests
  /// set it high to compare.
  std::size_t own_group_entries = 16384;
};
/// Linearized backward Euler of Baraff & Witkin 1998 (integrator_implicit_euler.cpp).
std::unique_ptr<Integrator> make_implicit_euler(const ImplicitEulerOptions& options = {});

struct BlockSystem;
/// An integrator whose step solves a linear system A dv = b (implicit Euler): the system of
/// its last step, for the adjoint of that step (gradients/step_adjoint_implicit.cpp).
class LinearSystemStep {
 public:
  virtual ~LinearSystemStep() = default;
  /// out = A^T of the last step (storage reused) and whether A was symmetric; false (out
  /// untouched) when no step has solved a system yet.
  virtual bool last_system_transposed(BlockSystem& out, bool& symmetric) const = 0;
};
/// Extended position-based dynamics with small steps, Macklin, Müller & Chentanez 2016 and
/// Macklin et al. 2019, on the forces' constraints (integrator_xpbd.cpp, docs/xpbd.md).
std::unique_ptr<Integrator> make_xpbd(const XpbdSettings& settings);

}  // namespace pinsim
