// The grader and check-plugin against plugin tables that disagree with themselves
// (submissions/inconsistent.cpp), against source submissions whose copy must leave things
// out (links leaving the folder, a hard link to another owner's file, a FIFO), and an
// output folder that cannot be made.
#include <sys/stat.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "grade_cli.hpp"
#include "test_support.hpp"

using Catch::Matchers::Contains;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const fs::path subs = PINSIM_GRADING_SUBMISSIONS;
const fs::path src = PINSIM_GRADING_SOURCE;

using pinsim::test::grade;
using pinsim::test::Graded;

}  // namespace

TEST_CASE("tables: PINSIM_CAP_ENERGY without energy() fails the plugin, crashes nothing") {
  const fs::path lib = subs / "table_energy_flag_without_energy/libstudent_spring.so";
  // check-plugin: refused at load, naming the flag and the missing function.
  const auto c = pinsim::test::pinsim_cli("check-plugin " + lib.string() + " 2>&1");
  CHECK(c.code == 2);
  CHECK_THAT(c.output, Contains("inconsistent plugin table of 'linear_spring'"));
  CHECK_THAT(c.output, Contains("declares PINSIM_CAP_ENERGY but its energy function is NULL"));
  // The grader: every test of the plugin fails with that message; the grade finishes.
  const Graded g = grade(src / "rubric_springs.json", lib.parent_path(), "energy");
  CHECK(g.code == 0);
  CHECK(g.results["score"] == 0);
  REQUIRE(g.results["tests"].size() == 7);
  CHECK_THAT(g.results["tests"][0]["output"].get<std::string>(),
             Contains("declares PINSIM_CAP_ENERGY but its energy function is NULL"));
  CHECK(g.results["output"].get<std::string>().find("did not finish") == std::string::npos);
}

TEST_CASE("tables: a description forged on the channel is checked by the grader too") {
  const Graded g = grade(src / "rubric_springs.json", subs / "table_forged_description", "forged");
  CHECK(g.code == 0);
  CHECK(g.results["score"] == 0);
  REQUIRE(g.results["tests"].size() == 7);
  const std::string out = g.results["tests"][0]["output"].get<std::string>();
  CAPTURE(out);
  CHECK_THAT(out, Contains("inconsistent table"));
  CHECK_THAT(out, Contains("declares PINSIM_CAP_ENERGY but its energy function is NULL"));
}

TEST_CASE("tables: the copy follows links inside, leaves out what is not the submitter's") {
  const fs::path base = pinsim::test::temp_dir("tables-copy");
  const fs::path d = base / "submission";
  fs::create_directories(d / "hdr");
  fs::copy_file(src / "submissions/correct_source/student_spring.hpp",
                d / "hdr/student_spring.hpp");
  fs::copy_file(src / "submissions/correct_source/spring.cpp", d / "spring.cpp");
  fs::create_symlink("spring.cpp", d / "spring_link.cpp");  // followed: inside
  fs::create_directory_symlink("hdr", d / "inc");           // a folder inside
  fs::create_symlink("/etc/passwd", d / "passwd.txt");      // outside: left out
  fs::create_symlink("../outside.txt", d / "up.txt");       // outside: left out
  REQUIRE(::mkfifo((d / "pipe").c_str(), 0644) == 0);       // left out
  pinsim::test::write_file(
      d / "CMakeLists.txt",
      "cmake_minimum_required(VERSION 3.25)\nproject(student CXX)\n"
      "find_package(pinsim REQUIRED)\n"
      "pinsim_add_plugin(linear_spring spring_link.cpp)\n"
      "target_include_directories(pinsim_plugin_linear_spring PRIVATE inc)\n"
      "foreach(f secret.txt passwd.txt)\n  if(EXISTS ${CMAKE_SOURCE_DIR}/${f})\n"
      "    file(READ ${CMAKE_SOURCE_DIR}/${f} t)\n"
      "    message(WARNING \"${f}: ${t}\")\n  endif()\nendforeach()\n");
  // A secret of another owner, hard-linked in: only possible to test as root, where the
  // submission can belong to someone else.
  const bool root = ::geteuid() == 0;
  if (root) {
    pinsim::test::write_file(base / "secret", "TOP-SECRET-CONTENTS\n");
    ::chmod((base / "secret").c_str(), 0600);
    fs::create_hard_link(base / "secret", d / "secret.txt");
    for (const auto& e : fs::recursive_directory_iterator(d))
      if (e.path().filename() != "secret.txt") REQUIRE(::lchown(e.path().c_str(), 4242, 4242) == 0);
    REQUIRE(::chown(d.c_str(), 4242, 4242) == 0);
  }
  // The spring's #include "student_spring.hpp" is found through inc/ -> hdr/.
  const Graded g = grade(src / "rubric_hostile.json", d, "copy");
  const std::string first = g.results["tests"][0]["output"].get<std::string>();
  CAPTURE(first);
  CHECK(g.results["score"] == 7);
  CHECK_THAT(first, Contains("Left out of the copy of your submission"));
  CHECK_THAT(first, Contains("passwd.txt: a symlink to /etc/passwd, outside the submission"));
  CHECK_THAT(first, Contains("up.txt: a symlink to ../outside.txt, outside the submission"));
  CHECK_THAT(first, Contains("pipe: a FIFO"));
  const std::string all = g.results.dump();
  CHECK(all.find("root:") == std::string::npos);
  if (root) {
    CHECK_THAT(first, Contains("secret.txt: a hard link to a file of another owner (uid 0)"));
    CHECK(all.find("TOP-SECRET") == std::string::npos);
  }
  // Said once: only the first test carries the list.
  for (std::size_t i = 1; i < g.results["tests"].size(); ++i)
    CHECK(g.results["tests"][i]["output"].get<std::string>().find("Left out") == std::string::npos);
}

TEST_CASE("tables: an output folder that cannot be made is exit 2 with the reason") {
  const auto r = pinsim::test::pinsim_cli(
      "-q grade --rubric " + (src / "rubric_hostile.json").string() + " --submission " +
      (subs / "sign_error").string() + " --out /proc/version/results 2>&1");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("cannot make the output folder /proc/version/results"));
  CHECK(r.output.find("results written") == std::string::npos);
}
