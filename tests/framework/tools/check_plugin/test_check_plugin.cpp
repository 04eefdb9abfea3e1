// check-plugin passes every shipped force plugin (in each mode) and fails, naming the check,
// on deliberately wrong fixtures.
#include <catch2/catch.hpp>
#include <cstdio>
#include <string>

#include "test_support.hpp"
#include "tools/check_layout.hpp"
#include "tools/plugin_check.hpp"

namespace {

pinsim::CheckReport check(const std::string& name, nlohmann::json params = nlohmann::json::object(),
                          bool assume_internal = false) {
  pinsim::PluginLoader loader(pinsim::plugin_search_dirs());
  auto p = loader.load(name);
  pinsim::CheckOptions o;
  o.params = std::move(params);
  o.assume_internal = assume_internal;
  return pinsim::check_force_plugin(*p, o);
}

pinsim::CheckReport check_fixture(const std::string& file) {
  auto p = pinsim::load_plugin_file(std::string(PINSIM_TEST_FIXTURE_DIR) + "/" + file);
  return pinsim::check_force_plugin(*p, {});
}

/// Every check that ran passed, and the ones a plugin of this kind must run did run.
void require_pass(const pinsim::CheckReport& r, std::initializer_list<const char*> must_run) {
  INFO(pinsim::format_report(r));
  CHECK(r.passed());
  for (const char* name : must_run) {
    const pinsim::CheckResult* c = r.find(name);
    REQUIRE(c != nullptr);
    CHECK(c->status == pinsim::CheckStatus::Pass);
  }
}

/// Every shipped internal force but area_pressure also gives its parameter derivatives
/// (dparam) and its Jacobians' products (jacobian_products).
const std::initializer_list<const char*> kInternal = {
    "gradient",         "dfdx",       "dfdv",   "momentum",         "angular_momentum",
    "rigid_invariance", "degenerate", "dparam", "jacobian_products"};
/// A damped internal force also runs the dissipation check.
const std::initializer_list<const char*> kDamped = {
    "gradient",         "dfdx",       "dfdv",        "momentum", "angular_momentum",
    "rigid_invariance", "degenerate", "dissipation", "dparam",   "jacobian_products"};
/// The forces that give both in one call (ABI 4.5) also run adjoint_products.
const std::initializer_list<const char*> kFused = {"dparam", "jacobian_products",
                                                   "adjoint_products"};

/// The named check was skipped (the plugin does not claim what it checks).
void require_skip(const pinsim::CheckReport& r, const std::string& name) {
  INFO(pinsim::format_report(r));
  const pinsim::CheckResult* c = r.find(name);
  REQUIRE(c != nullptr);
  CHECK(c->status == pinsim::CheckStatus::Skip);
}

/// The named check failed, and it is the only failure unless `others` allows more.
void require_fail(const pinsim::CheckReport& r, const std::string& name) {
  INFO(pinsim::format_report(r));
  CHECK_FALSE(r.passed());
  const pinsim::CheckResult* c = r.find(name);
  REQUIRE(c != nullptr);
  CHECK(c->status == pinsim::CheckStatus::Fail);
  CHECK(pinsim::format_report(r).find("FAIL  " + name) != std::string::npos);
}

}  // namespace

TEST_CASE("shipped: linear_spring, finite and zero rest length") {
  require_pass(check("linear_spring"), kInternal);
  require_pass(check("linear_spring", {{"rest_length", 0.0}}), kInternal);
  require_pass(check("linear_spring", {{"rest_length", 0.4}}), kInternal);
  require_skip(check("linear_spring"), "dissipation");  // declares no damping
}

TEST_CASE("shipped: damped_spring") {
  require_pass(check("damped_spring"), kDamped);
  require_pass(check("damped_spring", {{"kd", 0.0}, {"rest_length", 0.0}}), kDamped);
}

TEST_CASE("shipped: bending, flat, initial and fixed rest angle") {
  require_pass(check("bending"), kInternal);
  require_pass(check("bending", {{"shape", "initial"}}), kInternal);
  require_pass(check("bending", {{"shape", "angle"}, {"rest_angle", -2.0}}), kInternal);
  require_pass(check("bending", {{"shape", "initial"}, {"length_scaled", true}}), kInternal);
}

TEST_CASE("shipped: gravity, uniform and pairwise") {
  require_pass(check("gravity"),
               {"gradient", "dfdx", "dfdv", "degenerate", "dparam", "jacobian_products"});
  require_pass(check("gravity", {{"g", {1.5, -3.0}}}), {"dparam"});
  require_skip(check("gravity"), "dissipation");
  for (double alpha : {-1.0, 0.0, 1.5})
    for (double eps : {0.0, 0.05})
      require_pass(
          check("gravity", {{"mode", "pairwise"}, {"alpha", alpha}, {"softening", eps}}, true),
          kInternal);
}

TEST_CASE("a ConstraintSpring with only C and dC/dp passes (numerical Hessian)") {
  require_pass(check_fixture("libfixture_cs_triangle_area.so"), kDamped);
}

const std::initializer_list<const char*> kConstraints = {"constraint_energy", "constraint_force",
                                                         "constraint_gradient"};

TEST_CASE("shipped: the constraint entries agree with energy, force and differences of C") {
  require_pass(check("linear_spring"), kConstraints);
  require_pass(check("linear_spring", {{"rest_length", 0.0}}), kConstraints);
  require_pass(check("damped_spring"), kConstraints);
  require_pass(check("bending"), kConstraints);
  require_pass(check("bending", {{"shape", "initial"}, {"length_scaled", true}}), kConstraints);
  require_pass(check("area_pressure", {{"kd", 3.0}}), kConstraints);
  // a plugin without constraints is not one check short
  const auto g = check("gravity");
  CHECK(g.find("constraint_energy") == nullptr);
  CHECK(g.find("constraint_gradient") == nullptr);
}

TEST_CASE("fixture whose constraints misstate ks or dC/dp fails those checks") {
  auto p = pinsim::load_plugin_file(std::string(PINSIM_TEST_FIXTURE_DIR) +
                                    "/libfixture_wrong_constraint.so");
  auto with = [&](const char* mistake) {
    pinsim::CheckOptions o;
    o.params = {{"mistake", mistake}};
    return pinsim::check_force_plugin(*p, o);
  };
  require_pass(with("none"), kConstraints);
  // ks = 2k: sum ks/2 C^2 changes twice as much as E, and -J^T ks C is twice the force
  const auto ks = with("ks");
  require_fail(ks, "constraint_energy");
  CHECK(ks.find("constraint_energy")->worst == Approx(1.0 / 3.0).epsilon(1e-6));
  require_fail(ks, "constraint_force");
  CHECK(ks.find("constraint_gradient")->status == pinsim::CheckStatus::Pass);
  CHECK(ks.find("gradient")->status == pinsim::CheckStatus::Pass);  // the force itself is right
  // dC/dp 1 % long: differences of C disagree by 1 %, at both steps
  const auto grad = with("gradient");
  require_fail(grad, "constraint_gradient");
  CHECK(grad.find("constraint_gradient")->worst == Approx(0.01 / 1.01).epsilon(1e-3));
  CHECK(grad.find("constraint_energy")->status == pinsim::CheckStatus::Pass);
}

TEST_CASE("fixture with a sign error fails the gradient check") {
  const auto r = check_fixture("libfixture_wrong_sign.so");
  require_fail(r, "gradient");
  CHECK(r.find("gradient")->worst == Approx(1.0).epsilon(1e-3));  // f = +∇E: |f - (-∇E)| = 2|f|
}

TEST_CASE("fixture missing the factor 1/2 in E fails the gradient check") {
  const auto r = check_fixture("libfixture_wrong_half.so");
  require_fail(r, "gradient");
  CHECK(r.find("dfdx")->status == pinsim::CheckStatus::Pass);  // the force itself is right
  CHECK(r.find("gradient")->detail.find("does not converge") != std::string::npos);
}

TEST_CASE("fixture with a wrong Jacobian fails the dfdx check only") {
  const auto r = check_fixture("libfixture_wrong_jacobian.so");
  require_fail(r, "dfdx");
  CHECK(r.find("gradient")->status == pinsim::CheckStatus::Pass);
}

TEST_CASE("parameter derivatives: a wrong one fails, at a bound the other side is used") {
  // d f / d k counted twice: |2 g - g| / (|2 g| + |g|) = 1/3 at both steps
  const auto r = check_fixture("libfixture_wrong_dparam.so");
  require_fail(r, "dparam");
  CHECK(r.find("dparam")->worst == Approx(1.0 / 3.0).epsilon(1e-3));
  CHECK(r.find("dparam")->detail.find("d k at k = 10") != std::string::npos);
  CHECK(r.find("gradient")->status == pinsim::CheckStatus::Pass);
  // kd = 0 sits on its bound (min 0): the one-sided difference still checks it
  require_pass(check("damped_spring", {{"kd", 0.0}}), {"dparam"});
  require_pass(check("area_pressure", {{"kd", 0.0}}), {"dparam"});
  // a plugin without the entry is not one check short
  CHECK(check_fixture("libfixture_wrong_jacobian.so").find("dparam") == nullptr);
}

TEST_CASE("Jacobian products: wrong ones fail, against the plugin's own entries") {
  // the products drop the (1 - L/R)(I - R̂R̂ᵀ) term that the Jacobian's entries have
  const auto r = check_fixture("libfixture_wrong_products.so");
  require_fail(r, "jacobian_products");
  CHECK(r.find("dfdx")->status == pinsim::CheckStatus::Pass);
  CHECK(r.find("jacobian_products")->worst > 1e-3);
  // area_pressure forms its entries only: not one check short
  CHECK(check("area_pressure").find("jacobian_products") == nullptr);
  require_pass(check("damped_spring", {{"kd", 0.0}}), {"jacobian_products"});
  require_pass(check("gravity", {{"mode", "pairwise"}, {"alpha", 0.5}}), {"jacobian_products"});
}

TEST_CASE("fused products: a wrong one fails, against the plugin's separate entries") {
  // w . d f / d k with its sign flipped: |-y - y| / (sum of the terms' sizes) >= 2 |y| / ...
  const auto r = check_fixture("libfixture_wrong_adjoint_products.so");
  require_fail(r, "adjoint_products");
  CHECK(r.find("dparam")->status == pinsim::CheckStatus::Pass);
  CHECK(r.find("jacobian_products")->status == pinsim::CheckStatus::Pass);
  CHECK(r.find("adjoint_products")->worst > 1e-3);
  CHECK(r.find("adjoint_products")->detail.find("w . d f / d k") != std::string::npos);
  // the shipped fused ones, and ConstraintSpring's generic one
  require_pass(check("linear_spring"), kFused);
  require_pass(check("linear_spring", {{"rest_length", 0.0}}), kFused);
  require_pass(check("gravity", {{"g", {1.5, -3.0}}}), kFused);
  require_pass(check("gravity", {{"mode", "pairwise"}, {"alpha", 0.5}, {"softening", 0.05}}, true),
               kFused);
  require_pass(check("damped_spring"), kFused);
  require_pass(check("damped_spring", {{"kd", 0.0}, {"rest_length", 0.0}}), kFused);
  require_pass(check("bending"), kFused);
  require_pass(check("bending", {{"shape", "angle"}, {"rest_angle", 1.0}}), kFused);
  require_pass(check("bending", {{"shape", "initial"}, {"length_scaled", true}}), kFused);
  require_pass(check_fixture("libfixture_cs_triangle_area.so"), kFused);
  // a plugin without the entry is not one check short
  CHECK(check("area_pressure").find("adjoint_products") == nullptr);
  // the products counted twice in the fused entry only: its (df/dx)^T w half fails
  const auto gx = check_fixture("libfixture_wrong_adjoint_gx.so");
  require_fail(gx, "adjoint_products");
  CHECK(gx.find("jacobian_products")->status == pinsim::CheckStatus::Pass);
  CHECK(gx.find("adjoint_products")->detail.find("(df/dx)^T w") != std::string::npos);
}

TEST_CASE("fused products: ConstraintSpring's finds its slots by name, takes an override") {
  // bias (a vec2, a uniform force: not a constraint, so constraint_force fails by design), a
  // string, then kd before ks: the slots ks and kd are found by name, bias from the class's
  // add_dforce_dparam
  const auto layout = check_fixture("libfixture_cs_param_layout.so");
  INFO(pinsim::format_report(layout));
  for (const char* name :
       {"gradient", "dfdx", "dfdv", "dparam", "jacobian_products", "adjoint_products"}) {
    INFO(name);
    REQUIRE(layout.find(name) != nullptr);
    CHECK(layout.find(name)->status == pinsim::CheckStatus::Pass);
  }
  // a class's own add_jacobian_products (doubled here) is what the fused entry gives
  const auto own = check_fixture("libfixture_cs_wrong_products.so");
  require_fail(own, "jacobian_products");
  CHECK(own.find("adjoint_products")->status == pinsim::CheckStatus::Pass);
}

TEST_CASE("fixture that divides by zero at a degenerate state fails the degenerate check") {
  const auto r = check_fixture("libfixture_wrong_nan.so");
  require_fail(r, "degenerate");
  CHECK(r.find("gradient")->status == pinsim::CheckStatus::Pass);
}

TEST_CASE("an unconverged small error does not pass by luck") {
  // The step-halving rule: the discrepancy must be tiny, or shrink ~4x when h halves.
  // The wrong-half fixture has a constant relative error 1/3 at both steps.
  const auto r = check_fixture("libfixture_wrong_half.so");
  CHECK(r.find("gradient")->worst == Approx(1.0 / 3.0).epsilon(1e-3));
}

TEST_CASE("pinsim check-plugin: exit status and report name the failing check") {
  const auto dir = pinsim::test::temp_dir("check_plugin");
  const std::string out = (dir / "out.txt").string();
  const std::string bad = std::string(PINSIM_BIN) + " check-plugin " + PINSIM_TEST_FIXTURE_DIR +
                          "/libfixture_wrong_jacobian.so > " + out + " 2>&1";
  const int rc_bad = std::system(bad.c_str());
  CHECK(WEXITSTATUS(rc_bad) == 1);
  CHECK(pinsim::test::read_file(out).find("FAIL  dfdx") != std::string::npos);
  const std::string good = std::string(PINSIM_BIN) + " check-plugin bending > " + out + " 2>&1";
  CHECK(WEXITSTATUS(std::system(good.c_str())) == 0);
  CHECK(pinsim::test::read_file(out).find("PASS: bending") != std::string::npos);
}

TEST_CASE("topologies: the shipped pair and triple forces pass on rings, grids and bodies") {
  for (const std::string& topology : pinsim::check_topologies()) {
    INFO("topology " << topology);
    pinsim::PluginLoader loader(pinsim::plugin_search_dirs());
    for (const char* name : {"linear_spring", "damped_spring", "bending", "gravity"}) {
      pinsim::CheckOptions o;
      o.topology = topology;
      const auto r = pinsim::check_force_plugin(*loader.load(name), o);
      INFO(pinsim::format_report(r));
      CHECK(r.passed());
      CHECK(r.layout.rfind("topology " + topology + ":", 0) == 0);
    }
  }
}

TEST_CASE("topology: a ring force over edge pairs fails on an open chain, passes on a ring") {
  // The fixture sums the shoelace terms of its pairs: an area only when they close a ring.
  const auto p = pinsim::load_plugin_file(std::string(PINSIM_TEST_FIXTURE_DIR) +
                                          "/libpinsim_plugin_ring_area_pairs.so");
  pinsim::CheckOptions chain;
  const auto open = pinsim::check_force_plugin(*p, chain);
  require_fail(open, "momentum");
  CHECK(open.find("rigid_invariance")->status == pinsim::CheckStatus::Fail);
  pinsim::CheckOptions ring;
  ring.topology = "ring";
  const auto closed = pinsim::check_force_plugin(*p, ring);
  require_pass(closed, {"gradient", "momentum", "angular_momentum", "rigid_invariance"});
  CHECK(closed.layout.find("8 elements of arity 2 (edges) on 8 particles") != std::string::npos);
}

TEST_CASE("topology: a topology without elements of the plugin's arity is a clear error") {
  // Whole-body layouts exist for every topology; a 4-particle stencil exists only on chains
  // and is refused elsewhere, naming the topology.
  CHECK_THROWS_WITH(pinsim::topology_layout("grid", 4),
                    Catch::Contains("--topology grid: has no elements of arity 4"));
  CHECK_THROWS_WITH(pinsim::topology_layout("torus", 2),
                    Catch::Contains("unknown topology (known: chain, ring, grid, body)"));
  const auto ring = pinsim::topology_layout("ring", 0);
  CHECK(ring.count == 1);
  CHECK(ring.elements == std::vector<uint32_t>{8, 0, 1, 2, 3, 4, 5, 6, 7});
  const auto body = pinsim::topology_layout("body", 0);
  CHECK(body.count == 2);  // a ring of 7 and a 3 x 3 grid
  CHECK(body.elements.size() == 2 + 7 + 9);
}

TEST_CASE("pinsim check-plugin --scene checks a scene's own force on its own elements") {
  const std::string scene = std::string(PINSIM_SOURCE_DIR) + "/configs/blob_pressure.json";
  auto r =
      pinsim::test::pinsim_cli("check-plugin area_pressure --scene " + scene + " --force-index 2");
  INFO(r.output);
  CHECK(r.code == 0);
  CHECK(r.output.find("forces[2] (area_pressure): 1 whole-body elements on the scene's 24 "
                      "particles") != std::string::npos);
  CHECK(r.output.find("PASS: area_pressure") != std::string::npos);
  // Without a name the scene's force is checked; a mismatched name is refused.
  r = pinsim::test::pinsim_cli("check-plugin --scene " + scene + " --force-index 1");
  CHECK(r.code == 0);
  CHECK(r.output.find("PASS: damped_spring") != std::string::npos);
  r = pinsim::test::pinsim_cli("check-plugin bending --scene " + scene + " --force-index 2");
  CHECK(r.code == 2);
  CHECK(r.output.find("forces[2].type: is 'area_pressure', not the plugin checked ('bending')") !=
        std::string::npos);
  r = pinsim::test::pinsim_cli("check-plugin --scene " + scene + " --force-index 9");
  CHECK(r.code == 2);
  CHECK(r.output.find("--force-index 9: the scene has 3 force(s)") != std::string::npos);
}

TEST_CASE("pinsim check-plugin --plugin-path finds an out-of-tree plugin by name") {
  // Without the folder on a search path the name is not found; with it, it is.
  auto r = pinsim::test::pinsim_cli("check-plugin ring_area_pairs --topology ring");
  CHECK(r.code == 2);
  r = pinsim::test::pinsim_cli(std::string("check-plugin ring_area_pairs --topology ring ") +
                               "--plugin-path " + PINSIM_TEST_FIXTURE_DIR);
  INFO(r.output);
  CHECK(r.code == 0);
  CHECK(r.output.find("PASS: ring_area_pairs") != std::string::npos);
}
