// check-plugin passes every shipped force plugin (in each mode) and fails, naming the check,
// on deliberately wrong fixtures.
#include <catch2/catch.hpp>
#include <cstdio>
#include <string>

#include "test_support.hpp"
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

const std::initializer_list<const char*> kInternal = {
    "gradient",         "dfdx",       "dfdv",       "momentum", "angular_momentum",
    "rigid_invariance", "degenerate", "dissipation"};

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
}

TEST_CASE("shipped: damped_spring") {
  require_pass(check("damped_spring"), kInternal);
  require_pass(check("damped_spring", {{"kd", 0.0}, {"rest_length", 0.0}}), kInternal);
}

TEST_CASE("shipped: bending, flat, initial and fixed rest angle") {
  require_pass(check("bending"), kInternal);
  require_pass(check("bending", {{"shape", "initial"}}), kInternal);
  require_pass(check("bending", {{"shape", "angle"}, {"rest_angle", -2.0}}), kInternal);
  require_pass(check("bending", {{"shape", "initial"}, {"length_scaled", true}}), kInternal);
}

TEST_CASE("shipped: gravity, uniform and pairwise") {
  require_pass(check("gravity"), {"gradient", "dfdx", "dfdv", "degenerate", "dissipation"});
  for (double alpha : {-1.0, 0.0, 1.5})
    for (double eps : {0.0, 0.05})
      require_pass(
          check("gravity", {{"mode", "pairwise"}, {"alpha", alpha}, {"softening", eps}}, true),
          kInternal);
}

TEST_CASE("a ConstraintSpring with only C and dC/dp passes (numerical Hessian)") {
  require_pass(check_fixture("libfixture_cs_triangle_area.so"), kInternal);
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
