// The block solvers shared by implicit Euler and its adjoint (core/block_krylov.hpp): the
// transpose of a block matrix in its own and in a transposed pattern against the dense
// transpose, conjugate gradients and BiCGSTAB against a dense LU solve, and the system that
// implicit Euler hands to the adjoint (A^T, A = M - h D - h^2 K) against one assembled from
// the forces' Jacobians.
#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <utility>
#include <vector>

#include "core/block_krylov.hpp"
#include "core/integrators.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "test_support.hpp"

using namespace pinsim;

namespace {

/// A block system with the blocks at `where` (block row, block column; sorted, the diagonal
/// included) taken from the dense matrix d.
BlockSystem blocks_of(const Eigen::MatrixXd& d, const std::vector<std::pair<int, int>>& where) {
  BlockSystem s;
  const int np = static_cast<int>(d.rows() / 2);
  s.a.first.assign(static_cast<std::size_t>(np) + 1, 0);
  for (const auto& [i, j] : where) {
    ++s.a.first[static_cast<std::size_t>(i) + 1];
    s.a.col.push_back(j);
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < 2; ++c) s.a.value.push_back(d(2 * i + r, 2 * j + c));
  }
  for (int i = 0; i < np; ++i)
    s.a.first[static_cast<std::size_t>(i) + 1] += s.a.first[static_cast<std::size_t>(i)];
  s.index();
  return s;
}

Eigen::MatrixXd dense(const BlockSystem& s) { return Eigen::MatrixXd(s.a.to_eigen()); }

/// A random dense matrix zero outside the blocks at `where` (entries in [-1, 1]) plus 8 on
/// the diagonal: strictly diagonally dominant for up to 7 off-diagonal entries a row.
Eigen::MatrixXd random_blocks(int np, const std::vector<std::pair<int, int>>& where) {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(2 * np, 2 * np);
  const Eigen::MatrixXd r = Eigen::MatrixXd::Random(2 * np, 2 * np);
  for (const auto& [i, j] : where) d.block<2, 2>(2 * i, 2 * j) = r.block<2, 2>(2 * i, 2 * j);
  d.diagonal().array() += 8.0;
  return d;
}

}  // namespace

TEST_CASE("block system: transpose in its own and in the transposed pattern") {
  std::srand(7);
  // a pattern holding every transpose, then one that does not ((0,2) without (2,0), (2,1)
  // without (1,2))
  const std::vector<std::pair<int, int>> sym{{0, 0}, {0, 1}, {1, 0}, {1, 1}, {2, 2}},
      asym{{0, 0}, {0, 2}, {1, 1}, {2, 1}, {2, 2}};
  for (const auto& where : {sym, asym}) {
    const Eigen::MatrixXd d = random_blocks(3, where);
    const BlockSystem s = blocks_of(d, where);
    CHECK(s.symmetric_pattern() == (where == sym));
    BlockSystem t;
    s.transpose_into(t);
    CHECK((dense(t) - d.transpose()).cwiseAbs().maxCoeff() == 0.0);
    // rows in order, each row's columns increasing, diagonal blocks found
    for (int64_t i = 0; i < t.a.rows(); ++i) {
      for (int64_t k = t.a.first[static_cast<std::size_t>(i)] + 1;
           k < t.a.first[static_cast<std::size_t>(i) + 1]; ++k)
        CHECK(t.a.col[static_cast<std::size_t>(k - 1)] < t.a.col[static_cast<std::size_t>(k)]);
      CHECK(t.diag_block[static_cast<std::size_t>(i)] >= 0);
    }
  }
}

TEST_CASE("block solvers: conjugate gradients and BiCGSTAB against dense LU") {
  std::srand(11);
  const int np = 6;
  std::vector<std::pair<int, int>> where;  // a chain: each particle and its neighbours
  for (int i = 0; i < np; ++i)
    for (int j = std::max(0, i - 1); j <= std::min(np - 1, i + 1); ++j) where.emplace_back(i, j);
  Eigen::MatrixXd nonsym = random_blocks(np, where);
  const Eigen::MatrixXd spd = 0.5 * (nonsym + nonsym.transpose());  // dominant: definite
  const Eigen::VectorXd b = Eigen::VectorXd::Random(2 * np);
  for (const bool symmetric : {true, false}) {
    const Eigen::MatrixXd& d = symmetric ? spd : nonsym;
    const BlockSystem s = blocks_of(d, where);
    std::vector<double> root;
    CHECK(s.is_symmetric(root) == symmetric);
    BlockKrylov k;
    k.resize(np);
    Eigen::VectorXd x = Eigen::VectorXd::Zero(2 * np), r = b;
    const double bb = b.squaredNorm();
    const BlockKrylov::Solve out =
        symmetric ? k.cg(s, bb, x, r, 100) : k.bicgstab(s, b, bb, x, r, 100);
    CHECK(out.converged);
    CHECK(out.iterations >= 1);
    const Eigen::VectorXd want = d.partialPivLu().solve(b);
    CHECK((x - want).norm() <= 1e-11 * want.norm());
    // residual_of at another point: r = b - A y and |r|^2
    const Eigen::VectorXd y = Eigen::VectorXd::Random(2 * np);
    Eigen::VectorXd ry(2 * np);
    CHECK(k.residual_of(s, b, y, ry) == Approx((b - d * y).squaredNorm()).epsilon(1e-13));
    CHECK((ry - (b - d * y)).cwiseAbs().maxCoeff() <= 1e-14);
  }
}

TEST_CASE("implicit Euler hands the adjoint A^T of its last step") {
  // a pinned chain of damped springs under gravity (A nonsymmetric once the springs turn)
  const nlohmann::json doc = nlohmann::json::parse(R"({"time": {"dt": 0.01, "duration": 0.2},
    "integrator": "implicit_euler",
    "bodies": [{"type": "strand", "name": "chain", "root": [0, 0], "direction": [1, 0],
                "count": 6, "segment_length": 0.1, "mass": 0.1, "pin": [0]}],
    "forces": [{"type": "gravity"},
               {"type": "damped_spring", "params": {"ks": 500, "kd": 0.5},
                "elements": {"body": "chain", "set": "edges"}}]})");
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(parse_scene(doc.dump(), "krylov", "."), loader);
  auto ie = make_implicit_euler();
  auto* linear = dynamic_cast<LinearSystemStep*>(ie.get());
  REQUIRE(linear != nullptr);
  BlockSystem at;
  bool symmetric = true;
  CHECK_FALSE(linear->last_system_transposed(at, symmetric));  // no step yet
  const double h = 0.01;
  for (int n = 0; n < 5; ++n) {
    const State s = sim.state();
    ie->step(sim, h);
    sim.state().t = (n + 1) * h;
    REQUIRE(linear->last_system_transposed(at, symmetric));
    // A = M - h D - h^2 K with the pinned particle's rows and columns the identity
    Eigen::SparseMatrix<double> K, D;
    sim.assemble_jacobians(s, K, D);
    const Eigen::Index n2 = 2 * static_cast<Eigen::Index>(s.size());
    Eigen::MatrixXd a = -h * Eigen::MatrixXd(D) - h * h * Eigen::MatrixXd(K);
    for (Eigen::Index i = 0; i < n2; ++i) {
      if (s.inv_mass[i / 2] > 0.0) {
        a(i, i) += 1.0 / s.inv_mass[i / 2];
        continue;
      }
      a.row(i).setZero();
      a.col(i).setZero();
      a(i, i) = 1.0;
    }
    INFO("step " << n + 1);
    CHECK((dense(at) - a.transpose()).cwiseAbs().maxCoeff() <= 1e-12 * a.cwiseAbs().maxCoeff());
    if (n > 0) CHECK_FALSE(symmetric);  // turning damped springs
  }
}
