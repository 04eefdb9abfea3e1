// The grader where namespaces are refused (container_like: Docker's default seccomp profile
// and capabilities): the fallback sandbox, said in results.json; refused when the grader is
// not root, and refused when a file the grader keeps to itself is within the uid's reach
// (no Landlock, and the rubric readable by anyone). The hostile suite runs in the fallback
// too (test_grading_hostile.cpp).
#include <sys/stat.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "test_support.hpp"

using Catch::Matchers::Contains;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const fs::path subs = PINSIM_GRADING_SUBMISSIONS;
const fs::path src = PINSIM_GRADING_SOURCE;

struct Graded {
  json results;
  int code = -1;
};

Graded grade_in_container(const std::string& options, const fs::path& out) {
  const auto r = pinsim::test::shell(
      std::string(PINSIM_CONTAINER_LIKE) + " " + options + " -- " + PINSIM_BIN +
      " -q grade --rubric " + (src / "rubric_hostile.json").string() + " --submission " +
      (subs / "hostile_bad_text").string() + " --out " + out.string() + " 2>&1");
  INFO(r.output.substr(0, 4000));
  REQUIRE(fs::exists(out / "results.json"));
  return {json::parse(pinsim::test::read_file(out / "results.json")), r.code};
}

}  // namespace

TEST_CASE("fallback: said in results.json, with Landlock where the kernel has it") {
  const fs::path out = pinsim::test::temp_dir("fallback-said");
  const Graded g = grade_in_container("", out);
  CHECK(g.code == 0);
  CHECK(g.results["score"] == 7);
  const auto& sandbox = g.results["extra_data"]["sandbox"];
  CHECK(sandbox["mode"] == "fallback");
  const std::string detail = sandbox["detail"].get<std::string>();
  CHECK_THAT(detail, Contains("namespaces are refused here"));
  CHECK_THAT(detail, Contains("unprivileged uid"));
  CHECK_THAT(detail, Contains("killed after each step"));
  // The output folder is the grader's alone.
  struct stat st {};
  REQUIRE(::stat(out.c_str(), &st) == 0);
  CHECK((st.st_mode & 077) == 0);
}

TEST_CASE("fallback: a grader that is not root cannot change uid, so it refuses") {
  if (::geteuid() != 0) {
    WARN("not root: cannot start the grader as another uid");
    return;
  }
  const fs::path out = pinsim::test::temp_dir("fallback-nonroot");
  REQUIRE(::chown(out.c_str(), 4242, 4242) == 0);
  const Graded g = grade_in_container("--uid 4242", out);
  CHECK(g.code == 2);
  CHECK(g.results["score"] == 0);
  const std::string why = g.results["output"].get<std::string>();
  CAPTURE(why);
  CHECK_THAT(why, Contains("cannot isolate submissions"));
  CHECK_THAT(why, Contains("namespaces are refused here"));
  CHECK_THAT(why, Contains("not root"));
  CHECK(g.results["extra_data"]["sandbox"]["mode"] == "none");
}

TEST_CASE("fallback: without Landlock, a rubric anyone can read makes the grader refuse") {
  // The build tree and the rubric are readable by every uid here: without Landlock nothing
  // keeps them from the submission, so nothing is run.
  const fs::path out = pinsim::test::temp_dir("fallback-exposed");
  const Graded g = grade_in_container("--no-landlock", out);
  CHECK(g.code == 2);
  CHECK(g.results["score"] == 0);
  const std::string why = g.results["output"].get<std::string>();
  CAPTURE(why);
  CHECK_THAT(why, Contains("the submission could reach"));
  CHECK_THAT(why, Contains("rubric_hostile.json (read)"));
  CHECK_THAT(why, Contains("chmod -R go-rwx"));
  CHECK_THAT(g.results["extra_data"]["sandbox"]["detail"].get<std::string>(),
             Contains("no Landlock here"));
}

TEST_CASE("fallback: the grader's log says which sandbox it uses, and why") {
  const fs::path out = pinsim::test::temp_dir("fallback-log");
  const auto r = pinsim::test::shell(std::string(PINSIM_CONTAINER_LIKE) + " -- " + PINSIM_BIN +
                                     " grade --rubric " + (src / "rubric_hostile.json").string() +
                                     " --submission " + (subs / "hostile_bad_text").string() +
                                     " --out " + out.string() + " 2>&1");
  INFO(r.output.substr(0, 4000));
  CHECK(r.code == 0);
  CHECK_THAT(r.output, Contains("sandbox: fallback, because namespaces are refused here"));
  CHECK_THAT(r.output, Contains("unprivileged uid"));
}
