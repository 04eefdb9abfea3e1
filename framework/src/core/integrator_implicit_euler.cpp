// Linearized backward Euler (Baraff & Witkin 1998, "Large steps in cloth simulation", eq. 6).
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>

#include "core/integrators.hpp"
#include "core/simulation.hpp"

namespace pinsim {
namespace {

/// Backward Euler v_{n+1} = v_n + h M^-1 f(x_{n+1}, v_{n+1}), x_{n+1} = x_n + h v_{n+1},
/// linearized once about (x_n, v_n) with K = df/dx, D = df/dv:
///   (M - h D - h^2 K) dv = h (f_n + h K v_n),   v_{n+1} = v_n + dv,
/// then the backend drifts x with v_{n+1}. Exact backward Euler for linear forces: on the
/// harmonic oscillator the energy shrinks by exactly 1/(1 + (h w)^2) per step, for any h.
/// Pinned dofs (inv_mass 0) keep dv = 0: their rows and columns become the identity.
/// The system is symmetric (K and D are for conservative and spring-damping forces) and is
/// solved by conjugate gradients with a Jacobi preconditioner to a relative residual of
/// 1e-12; if CG fails (an indefinite K from compressed springs can do that) a sparse LU
/// solves it instead. If that fails too (a singular system, or a residual above 1e-8 of
/// |b|), the step throws NumericError (solver_failure) rather than use an unconverged
/// velocity. stats() reports the solves for summary.json.
class ImplicitEuler : public Integrator {
 public:
  void step(Simulation& sim, double h) override {
    State& s = sim.state();
    sim.compute_forces(s, f_);
    sim.assemble_jacobians(s, K_, D_);
    const Eigen::Index n = 2 * static_cast<Eigen::Index>(s.size());
    const Eigen::Map<const Eigen::VectorXd> f(f_.data(), n), v0(s.v.data(), n);

    Eigen::VectorXd m(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const double w = s.inv_mass[i / 2];
      m[i] = w > 0.0 ? 1.0 / w : 0.0;
    }
    Eigen::VectorXd b = h * (f + h * (K_ * v0));
    A_ = -h * D_ - (h * h) * K_;
    // Zero the pinned rows and columns, then add M (1 on pinned diagonals).
    A_.prune([&](Eigen::Index r, Eigen::Index c, double) { return m[r] > 0.0 && m[c] > 0.0; });
    Eigen::SparseMatrix<double> M(n, n);
    std::vector<Eigen::Triplet<double>> diag;
    diag.reserve(static_cast<std::size_t>(n));
    for (Eigen::Index i = 0; i < n; ++i) {
      diag.emplace_back(static_cast<int>(i), static_cast<int>(i), m[i] > 0.0 ? m[i] : 1.0);
      if (!(m[i] > 0.0)) b[i] = 0.0;
    }
    M.setFromTriplets(diag.begin(), diag.end());
    A_ += M;

    cg_.setTolerance(1e-12);
    cg_.setMaxIterations(std::max<Eigen::Index>(100, 4 * n));
    cg_.compute(A_);
    Eigen::VectorXd dv = cg_.solve(b);
    ++solves_;
    cg_iterations_ += static_cast<uint64_t>(cg_.iterations());
    cg_iterations_max_ = std::max(cg_iterations_max_, static_cast<uint64_t>(cg_.iterations()));
    double residual = cg_.error();
    if (cg_.info() != Eigen::Success) {
      spdlog::debug(
          "implicit_euler: conjugate gradients stopped at residual {:.3g} after {} "
          "iterations; solving with sparse LU",
          cg_.error(), cg_.iterations());
      ++lu_fallbacks_;
      Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
      lu.compute(A_);
      const bool factored = lu.info() == Eigen::Success;
      if (factored) dv = lu.solve(b);
      const double bn = b.norm();
      residual = factored ? (A_ * dv - b).norm() / (bn > 0.0 ? bn : 1.0) : HUGE_VAL;
      if (!(residual <= 1e-8))
        throw NumericError(
            NumericError::Kind::SolverFailure,
            fmt::format("implicit_euler: the linear solve failed: conjugate gradients stopped "
                        "at relative residual {:.3g} after {} iterations, and sparse LU {}",
                        cg_.error(), cg_.iterations(),
                        factored ? fmt::format("left relative residual {:.3g}", residual)
                                 : std::string("could not factorize the system (singular?)")),
            sim.step_index() + 1, s.t, -1);
    }
    worst_residual_ = std::max(worst_residual_, residual);
    Eigen::Map<Eigen::VectorXd>(s.v.data(), n) += dv;
    sim.drift(s, h);
  }

  nlohmann::json stats() const override {
    return {
        {"linear_solves", solves_},
        {"cg_iterations_per_solve",
         solves_ > 0 ? static_cast<double>(cg_iterations_) / static_cast<double>(solves_) : 0.0},
        {"cg_iterations_max", cg_iterations_max_},
        {"worst_relative_residual", worst_residual_},
        {"lu_fallbacks", lu_fallbacks_}};
  }

 private:
  uint64_t solves_ = 0, cg_iterations_ = 0, cg_iterations_max_ = 0, lu_fallbacks_ = 0;
  double worst_residual_ = 0.0;
  Eigen::Matrix2Xd f_;
  Eigen::SparseMatrix<double> K_, D_, A_;
  Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg_;
};

}  // namespace

std::unique_ptr<Integrator> make_implicit_euler() { return std::make_unique<ImplicitEuler>(); }

}  // namespace pinsim
