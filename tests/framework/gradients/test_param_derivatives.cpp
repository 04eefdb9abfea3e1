// A force's derivatives in its parameters through a whole run: from the plugin's
// add_dforce_dparam (ABI 4.4) or add_adjoint_products (4.5) where it gives them, by central
// differences of the plugin otherwise, and the two against each other and against whole runs.
#include <catch2/catch.hpp>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "gradients/scene_gradient.hpp"
#include "whole_runs.hpp"

using namespace pinsim;
using namespace pinsim::grad;
using namespace pinsim::grad::testing;

namespace {

// Three bodies attracting pairwise, E = G m_k m_l R_s^alpha / alpha (gravity plugin, softened):
// its plugin gives d f / d G, not d f / d alpha.
const char* kCluster = R"({
  "time": {"dt": 0.001, "duration": 0.4},
  "backend": {"name": "none"},
  "particles": [
    {"x": [0.0, 0.0], "v": [0.0, 0.3], "mass": 1.0, "radius": 0.02},
    {"x": [1.0, 0.1], "v": [-0.2, 0.0], "mass": 2.0, "radius": 0.02},
    {"x": [0.3, 0.9], "v": [0.1, -0.1], "mass": 1.5, "radius": 0.02}
  ],
  "forces": [{"type": "gravity",
              "params": {"mode": "pairwise", "G": 0.8, "alpha": -1.0, "softening": 0.05}}]
})";

// A ring blob held by edge springs and an area force with damping, flying under gravity.
const char* kPressureBlob = R"({
  "time": {"dt": 0.001, "duration": 0.3},
  "backend": {"name": "none"},
  "bodies": [{"type": "ring_blob", "name": "blob", "center": [0.0, 1.0], "ring_radius": 0.3,
              "count": 10, "total_mass": 0.5, "radius": 0.02, "velocity": [0.3, 0.2]}],
  "forces": [
    {"type": "gravity"},
    {"type": "damped_spring", "params": {"ks": 200.0, "kd": 0.3, "rest_length": 0.17},
     "elements": {"body": "blob", "set": "edges"}},
    {"type": "area_pressure", "params": {"k": 4000.0, "kd": 20.0, "rest": "value",
                                         "rest_area": 0.3},
     "elements": {"body": "blob", "set": "boundary"}}
  ]
})";

// Three particles, a damped spring on each edge (rest lengths from the initial positions)
// and a stiff bending element on the triple, falling and flexing under gravity.
const char* kBentChain = R"({
  "time": {"dt": 0.001, "duration": 0.2},
  "backend": {"name": "none"},
  "particles": [
    {"x": [0.0, 1.0], "v": [0.0, 0.4], "mass": 0.1, "radius": 0.01},
    {"x": [0.2, 1.05], "v": [0.1, 0.0], "mass": 0.1, "radius": 0.01},
    {"x": [0.4, 0.95], "v": [0.0, -0.2], "mass": 0.1, "radius": 0.01}
  ],
  "forces": [
    {"type": "gravity"},
    {"type": "damped_spring", "params": {"ks": 300.0, "kd": 0.2}, "elements": [[0, 1], [1, 2]]},
    {"type": "bending", "params": {"k": 0.5}, "elements": [[0, 1, 2]]}
  ]
})";

const char* const kIntegrators[] = {"symplectic_euler", "velocity_verlet", "implicit_euler"};

}  // namespace

// The same gradient two ways: the plugins' derivatives d f / d theta, and central differences
// (f(theta + eps) - f(theta - eps)) / (2 eps) of instances created with theta moved
// (truncation zero here, every force being linear in these parameters; rounding about
// 1e-16 |f| / eps = 1e-10 relative per step). Implicit Euler with every derivative from its
// plugin differences nothing in a parameter (its second-order term differences the plugins'
// d f / d theta along the step instead).
TEST_CASE("parameter derivatives: the plugins' and central differences agree",
          "[gradients][scene]") {
  const std::string file = scene_file("grad_dparam_blob", kFlyingBlob);
  const std::vector<std::string> wrt{"forces[1].params.ks", "forces[1].params.kd",
                                     "forces[2].params.ks", "forces[0].params.g"};
  for (const char* integrator : kIntegrators) {
    INFO(integrator);
    const GradientReport a = gradient(file, {}, "target:3:0.2,0.8@0.2", wrt, integrator);
    const GradientReport b = gradient(file, {}, "target:3:0.2,0.8@0.2", wrt, integrator, 0, false);
    REQUIRE(a.paths.size() == wrt.size());
    CHECK(a.loss == b.loss);
    CHECK(a.state_hash == b.state_hash);
    for (std::size_t k = 0; k < wrt.size(); ++k) {
      CHECK(a.paths[k].plugin_derivative);
      CHECK_FALSE(b.paths[k].plugin_derivative);
      for (Eigen::Index c = 0; c < a.paths[k].gradient.size(); ++c) {
        const double ga = a.paths[k].gradient[c], gb = b.paths[k].gradient[c];
        INFO(wrt[k] << "[" << c << "]: plugin " << ga << ", differences " << gb);
        CHECK(std::abs(ga - gb) <= 1e-7 * std::max(std::abs(gb), 1e-3 * a.loss));
      }
    }
    const nlohmann::json ja = a.to_json(), jb = b.to_json();
    CHECK(ja["parameter derivative"]["method"] == "plugin");
    CHECK_FALSE(ja["parameter derivative"].contains("relative_step"));
    CHECK(ja["paths"]["forces[1].params.kd"]["parameter derivative"] == "plugin");
    CHECK(jb["parameter derivative"]["method"] == "finite differences");
    CHECK(jb["paths"]["forces[1].params.kd"]["parameter derivative"] == "finite differences");
    // the plugins' derivatives cost no force evaluations; the differences two per component.
    // damped_spring and gravity give theirs with their Jacobian products in one call (ABI 4.5
    // add_adjoint_products)
    CHECK(ja["cost"]["fused_product_evaluations"].get<uint64_t>() > 0);
    CHECK(jb["cost"]["parameter_derivative_evaluations"] == 0);
    CHECK(jb["cost"]["fused_product_evaluations"] == 0);
    CHECK(a.backward_force_evals < b.backward_force_evals);
  }
}

TEST_CASE("parameter derivatives: pairwise gravity's G from its plugin, alpha by differences",
          "[gradients][scene]") {
  const std::string file = scene_file("grad_dparam_cluster", kCluster);
  const std::vector<std::string> wrt{"forces[0].params.G", "forces[0].params.alpha",
                                     "forces[0].params.softening"};
  for (const char* integrator : kIntegrators)
    check_against_runs(file, {}, "final:2:x", wrt, integrator);
  const nlohmann::json j = gradient(file, {}, "final:2:x", wrt, "").to_json();
  CHECK(j["paths"]["forces[0].params.G"]["parameter derivative"] == "plugin");
  CHECK(j["paths"]["forces[0].params.alpha"]["parameter derivative"] == "finite differences");
  CHECK(j["parameter derivative"]["method"] == "plugin and finite differences");
  CHECK(j["parameter derivative"]["relative_step"] == 1e-6);
}

TEST_CASE("parameter derivatives: a blob's area stiffness and damping against whole runs",
          "[gradients][scene]") {
  const std::string file = scene_file("grad_dparam_area", kPressureBlob);
  for (const char* integrator : kIntegrators)
    check_against_runs(file, {}, "target:4:0.4,1.1",
                       {"forces[2].params.k", "forces[2].params.kd", "forces[1].params.kd"},
                       integrator);
}

// A force is asked for its fused products (ABI 4.5) only when every value differentiated in
// it is a parameter its plugin differentiates. Here the springs take their rest lengths from
// the initial positions, so with particles[1].x among the values they go through
// add_jacobian_products, add_dforce_dparam and the differenced rest lengths, while bending
// (flat rest shape, whatever the initial positions) keeps its fused call; both against whole
// runs.
TEST_CASE("parameter derivatives: fused and separate calls in one run, against whole runs",
          "[gradients][scene]") {
  const std::string file = scene_file("grad_dparam_chain", kBentChain);
  const std::vector<std::string> all{"forces[1].params.ks", "forces[2].params.k", "particles[1].x"};
  for (const char* integrator : kIntegrators) {
    INFO(integrator);
    check_against_runs(file, {}, "final:2:y", all, integrator);
    const nlohmann::json both = gradient(file, {}, "final:2:y", all, integrator).to_json();
    CHECK(both["cost"]["fused_product_evaluations"].get<uint64_t>() > 0);         // bending
    CHECK(both["cost"]["parameter_derivative_evaluations"].get<uint64_t>() > 0);  // springs' ks
    const nlohmann::json springs =
        gradient(file, {}, "final:2:y", {"forces[1].params.ks", "particles[1].x"}, integrator)
            .to_json();
    CHECK(springs["cost"]["fused_product_evaluations"] == 0);
  }
}
