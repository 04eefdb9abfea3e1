// The autograder against hostile submissions (submissions/hostile.cpp and source folders
// made here): forged verdicts, escaping processes, snooping, writing outside, the network,
// a fork bomb, floods and invalid text in the output, loading the reference plugin, hangs
// in create and at configure time, and a build in which one plugin does not compile. Each
// test asserts the exact score and message, that no process of the submission is left, that
// nothing was written outside the sandbox, and that the three result files are valid.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <thread>

#include "test_support.hpp"

using Catch::Matchers::Contains;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// What runs the grader in this section of a test: nothing (bubblewrap's sandbox), or
/// container_like, where namespaces are refused as in Docker and the fallback sandbox is used.
std::string g_launcher;
bool fallback() { return !g_launcher.empty(); }
/// Runs the enclosing test once in each sandbox.
#define IN_EACH_SANDBOX()                                                     \
  g_launcher = GENERATE(as<std::string>(), "", PINSIM_CONTAINER_LIKE " -- "); \
  CAPTURE(g_launcher)

const fs::path subs = PINSIM_GRADING_SUBMISSIONS;
const fs::path src = PINSIM_GRADING_SOURCE;
const fs::path hostile_rubric = src / "rubric_hostile.json";

struct Graded {
  json results;
  fs::path out;
  int exit_code = -1;
  double seconds = 0.0;
  std::string all_text;  ///< results.json, junit.xml and summary.txt, concatenated
};

/// Python checks that the three files are what their readers accept: strict UTF-8 JSON,
/// well-formed XML, UTF-8 text without raw control characters.
void check_files_valid(const fs::path& out) {
  static const fs::path script = [] {
    const fs::path p = pinsim::test::temp_dir("check-files") / "check_files.py";
    pinsim::test::write_file(p,
                             "import json, sys, xml.etree.ElementTree as ET\n"
                             "d = sys.argv[1]\n"
                             "for f in ('results.json', 'junit.xml', 'summary.txt'):\n"
                             "    text = open(d + '/' + f, 'rb').read().decode('utf-8')\n"
                             "    bad = [c for c in text if ord(c) < 32 and c not in '\\n\\t']\n"
                             "    assert not bad, (f, bad[:5])\n"
                             "json.loads(open(d + '/results.json', encoding='utf-8').read())\n"
                             "ET.parse(d + '/junit.xml')\n");
    return p;
  }();
  const auto r = pinsim::test::shell("python3 " + script.string() + " " + out.string());
  INFO(r.output);
  REQUIRE(r.code == 0);
}

Graded grade(const fs::path& rubric, const fs::path& submission, const std::string& tag,
             const std::string& extra = "", const std::string& env = "", fs::path out = {}) {
  Graded g;
  if (out.empty()) out = pinsim::test::temp_dir("hostile-" + tag);
  g.out = out;
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = pinsim::test::shell(env + " " + g_launcher + PINSIM_BIN + " -q grade --rubric " +
                                     rubric.string() + " --submission " + submission.string() +
                                     " --out " + out.string() + " " + extra + " 2>&1");
  g.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  g.exit_code = r.code;
  INFO(r.output.substr(0, 4000));
  REQUIRE(fs::exists(out / "results.json"));
  REQUIRE(fs::exists(out / "junit.xml"));
  REQUIRE(fs::exists(out / "summary.txt"));
  check_files_valid(out);
  g.results = json::parse(pinsim::test::read_file(out / "results.json"));
  // Which sandbox graded is said in results.json; the fallback only where namespaces are
  // refused.
  const char* mode = extra.find("--unsafe-no-sandbox") != std::string::npos ? "none"
                     : fallback()                                           ? "fallback"
                                                                            : "bubblewrap";
  if (g.exit_code == 0) CHECK(g.results["extra_data"]["sandbox"]["mode"] == mode);
  g.all_text = pinsim::test::read_file(out / "results.json") +
               pinsim::test::read_file(out / "junit.xml") +
               pinsim::test::read_file(out / "summary.txt");
  return g;
}

std::map<std::string, json> by_name(const json& results) {
  std::map<std::string, json> m;
  for (const auto& t : results["tests"]) m[t["name"].get<std::string>()] = t;
  return m;
}

double score(const Graded& g) { return g.results["score"].get<double>(); }

/// Host processes whose command line or name contains `marker` (none may outlive a grade).
std::vector<std::string> processes_with(const std::string& marker) {
  std::vector<std::string> found;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/proc", ec)) {
    const std::string pid = e.path().filename().string();
    if (pid.empty() || !std::isdigit(static_cast<unsigned char>(pid[0]))) continue;
    std::string cmd = pinsim::test::read_file(e.path() / "cmdline");
    for (auto& c : cmd)
      if (c == '\0') c = ' ';
    const std::string comm = pinsim::test::read_file(e.path() / "comm");
    const std::string stat = pinsim::test::read_file(e.path() / "stat");
    const auto close = stat.rfind(')');
    if (close != std::string::npos && close + 2 < stat.size() && stat[close + 2] == 'Z')
      continue;  // a zombie is dead (some containers have no init that reaps)
    if (cmd.find(marker) != std::string::npos || comm.find(marker) != std::string::npos)
      found.push_back(pid + ": " + cmd + comm);
  }
  return found;
}

fs::path hostile(const std::string& name) { return subs / ("hostile_" + name); }

/// A source submission made from the correct spring plus a CMakeLists.txt of our choice.
fs::path source_submission(const std::string& tag, const std::string& cmake_extra,
                           const std::string& spring_cpp = "") {
  const fs::path d = pinsim::test::temp_dir("source-" + tag);
  fs::copy_file(src / "submissions/correct_source/student_spring.hpp", d / "student_spring.hpp");
  if (spring_cpp.empty())
    fs::copy_file(src / "submissions/correct_source/spring.cpp", d / "spring.cpp");
  else
    pinsim::test::write_file(d / "spring.cpp", spring_cpp);
  pinsim::test::write_file(d / "CMakeLists.txt",
                           "cmake_minimum_required(VERSION 3.25)\nproject(student CXX)\n"
                           "find_package(pinsim REQUIRED)\n" +
                               cmake_extra + "\npinsim_add_plugin(linear_spring spring.cpp)\n");
  return d;
}

}  // namespace

TEST_CASE("hostile: a forged verdict on stdout or stderr scores nothing") {
  IN_EACH_SANDBOX();
  for (const std::string kind : {"forge_stdout", "forge_stderr"}) {
    CAPTURE(kind);
    const Graded g = grade(hostile_rubric, hostile(kind), kind);
    CHECK(g.exit_code == 0);
    CHECK(score(g) == 0);
    CHECK(g.results["max_score"].get<double>() == 7);
    const std::string out = g.results["tests"][0]["output"].get<std::string>();
    // The library quits while it is loaded: every test fails with that, never "forged".
    CHECK_THAT(out, Contains("exited (status 0) in the middle of the test"));
    CHECK_THAT(out, Contains("loading the library"));
    for (const auto& t : g.results["tests"]) CHECK(t["status"] == "failed");
  }
}

TEST_CASE("hostile: writing a forged reply on the grader's channel scores nothing") {
  IN_EACH_SANDBOX();
  const Graded g = grade(hostile_rubric, hostile("forge_channel"), "forge_channel");
  CHECK(score(g) == 0);
  CHECK_THAT(g.results["tests"][0]["output"].get<std::string>(), Contains("malformed reply"));
}

TEST_CASE("hostile: a double-forked setsid child dies with the sandbox and rewrites nothing") {
  IN_EACH_SANDBOX();
  const fs::path out = "/tmp/pinsim-hostile-escape-out";  // the path the fixture attacks
  fs::remove_all(out);
  fs::remove("/tmp/pinsim-hostile-escape-wrote");
  const Graded g = grade(hostile_rubric, hostile("escape"), "escape", "", "", out);
  CHECK(score(g) == 7);  // the physics is correct; forking changes nothing
  const std::string before = pinsim::test::read_file(out / "results.json");
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  CHECK(processes_with("pinsim-hostile-escape-marker").empty());
  CHECK(pinsim::test::read_file(out / "results.json") == before);
  CHECK_FALSE(fs::exists("/tmp/pinsim-hostile-escape-wrote"));
  fs::remove_all(out);
}

TEST_CASE("hostile: the sandbox shows no system, rubric, scene or other submission file") {
  IN_EACH_SANDBOX();
  const Graded g = grade(hostile_rubric, hostile("snoop"), "snoop");
  CHECK(score(g) == 7);
  const std::string out = g.results["tests"][1]["output"].get<std::string>();
  CAPTURE(out);
  CHECK_THAT(out, Contains("what your code printed"));
  CHECK_THAT(out, Contains("cannot read /etc/passwd"));
  CHECK_THAT(out, Contains("cannot read /etc/shadow"));
  // Not in the sandbox's view at all, or (the fallback) out of its uid's and Landlock's reach.
  const std::string absent = fallback() ? ": Permission denied" : ": No such file";
  CHECK_THAT(out, Contains("force_assignment.json" + absent));
  CHECK_THAT(out, Contains("spring_chain.json" + absent));
  CHECK_THAT(out, Contains("libstudent_spring.so" + absent));
  CHECK(out.find("READ ") == std::string::npos);
  CHECK(g.all_text.find("root:") == std::string::npos);
  CHECK(g.all_text.find("Blob Factory") == std::string::npos);
}

TEST_CASE("hostile: writing outside the sandbox changes nothing outside it") {
  IN_EACH_SANDBOX();
  for (const char* p :
       {"/tmp/pinsim-hostile-write-marker", PINSIM_SOURCE_DIR "/pinsim-hostile-write-marker"})
    fs::remove(p);
  const Graded g = grade(hostile_rubric, hostile("write_outside"), "write_outside");
  CHECK(score(g) == 7);
  const std::string out = g.results["tests"][1]["output"].get<std::string>();
  CAPTURE(out);
  CHECK_THAT(out, Contains("cannot write /submission/lib/pinsim-hostile-write-marker"));
  CHECK_THAT(out, Contains("cannot write /grader/pinsim-hostile-write-marker"));
  // The sandbox's own /tmp may be written; it is not the machine's.
  CHECK_FALSE(fs::exists("/tmp/pinsim-hostile-write-marker"));
  CHECK_FALSE(fs::exists(PINSIM_SOURCE_DIR "/pinsim-hostile-write-marker"));
  for (const auto& e : fs::directory_iterator(hostile("write_outside")))
    CHECK(e.path().filename() == "libstudent_spring.so");
}

TEST_CASE("hostile: the sandbox has no network") {
  IN_EACH_SANDBOX();
  const int s = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK, 0);
  REQUIRE(s >= 0);
  int one = 1;
  ::setsockopt(s, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(47613);
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  REQUIRE(::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0);  // port 47613 is free
  REQUIRE(::listen(s, 8) == 0);
  const Graded g = grade(hostile_rubric, hostile("network"), "network");
  CHECK(score(g) == 7);
  CHECK_THAT(g.results["tests"][1]["output"].get<std::string>(),
             Contains("connect to 127.0.0.1:47613 failed"));
  CHECK(::accept(s, nullptr, nullptr) < 0);  // nobody connected to the machine's loopback
  ::close(s);
}

TEST_CASE("hostile: a fork bomb in create is contained, reported, and leaves nothing") {
  IN_EACH_SANDBOX();
  const Graded g = grade(src / "rubric_hang.json", hostile("fork_bomb"), "fork_bomb");
  CHECK(score(g) == 1);  // loading passes; create never returns
  auto t = by_name(g.results);
  CHECK_THAT(t["f = -grad E"]["output"].get<std::string>(), Contains("wall-clock limit of 2 s"));
  CHECK_THAT(t["agrees with the reference"]["output"].get<std::string>(),
             Contains("hangs in create"));
  CHECK(g.seconds < 20);
  CHECK(processes_with("hostilebomb").empty());
}

TEST_CASE("hostile: 1 GiB of output is capped, counted, and changes no score") {
  IN_EACH_SANDBOX();
  const Graded g = grade(hostile_rubric, hostile("flood"), "flood");
  CHECK(score(g) == 7);
  CHECK(fs::file_size(g.out / "results.json") < 512 * 1024);
  CHECK_THAT(g.results["tests"][1]["output"].get<std::string>(), Contains("bytes not shown"));
  CHECK_THAT(g.results["tests"][1]["output"].get<std::string>(), Contains("(1073741824 bytes;"));
}

TEST_CASE("hostile: invalid UTF-8 and control characters in output give valid files") {
  IN_EACH_SANDBOX();
  const Graded g = grade(hostile_rubric, hostile("bad_text"), "bad_text");
  CHECK(score(g) == 7);
  const std::string out = g.results["tests"][1]["output"].get<std::string>();
  CAPTURE(out);
  CHECK_THAT(out, Contains("\\x1B[31mred"));  // escape codes shown as text
  CHECK_THAT(out, Contains("\xEF\xBF\xBD"));  // invalid bytes as U+FFFD
  CHECK_THAT(out, Contains("nul\\x00byte"));
  // check_files_valid (inside grade) parsed junit.xml despite "</failure>]]>" in the output.
}

TEST_CASE("hostile: the shipped reference plugin cannot be loaded from the sandbox") {
  IN_EACH_SANDBOX();
  const Graded g = grade(hostile_rubric, hostile("load_reference"), "load_reference");
  auto t = by_name(g.results);
  CHECK(t["agrees with the reference"]["status"] == "failed");
  CHECK(t["hanging chain"]["status"] == "failed");
  CHECK(score(g) == 3);  // load 1 + gradient 2 (zero force is consistent with zero energy)
  const std::string out = t["agrees with the reference"]["output"].get<std::string>();
  CAPTURE(out);
  CHECK_THAT(out, Contains("libpinsim_plugin_linear_spring.so: cannot open shared object file"));
  CHECK(out.find("LOADED") == std::string::npos);
}

TEST_CASE("hostile: sleeping forever in create costs one wall-clock limit, not one per test") {
  IN_EACH_SANDBOX();
  const Graded g = grade(src / "rubric_hang.json", hostile("sleep_in_create"), "sleep");
  CHECK(score(g) == 1);
  auto t = by_name(g.results);
  CHECK_THAT(t["f = -grad E"]["output"].get<std::string>(),
             Contains("did not finish within the wall-clock limit of 2 s"));
  CHECK_THAT(t["f = -grad E"]["output"].get<std::string>(), Contains("during create"));
  for (const char* name : {"agrees with the reference", "hanging chain"})
    CHECK(t[name]["output"] == "not run: 'linear_spring' hangs in create, see test 2");
  CHECK(g.seconds < 10);  // one 2 s limit, not three
}

TEST_CASE("hostile: CMake code runs sandboxed at configure time") {
  IN_EACH_SANDBOX();
  fs::remove("/tmp/pinsim-hostile-cmake-marker");
  const fs::path sub =
      source_submission("cmake_command",
                        "execute_process(COMMAND sh -c \"cat /etc/passwd; id; touch "
                        "/tmp/pinsim-hostile-cmake-marker; "
                        "touch " PINSIM_SOURCE_DIR
                        "/pinsim-hostile-cmake-marker\" OUTPUT_VARIABLE out ERROR_VARIABLE "
                        "err)\nmessage(WARNING \"configure saw: ${out} ${err}\")");
  const Graded g = grade(hostile_rubric, sub, "cmake_command");
  CHECK(score(g) == 7);
  CHECK(g.all_text.find("root:") == std::string::npos);
  CHECK_FALSE(fs::exists("/tmp/pinsim-hostile-cmake-marker"));
  CHECK_FALSE(fs::exists(PINSIM_SOURCE_DIR "/pinsim-hostile-cmake-marker"));
}

TEST_CASE("hostile: a configure step that hangs is stopped at the build limit") {
  // A duration of this test process's own, so that the check below cannot see another
  // test run's sleep on a shared machine.
  const std::string sleep = "sleep 600." + std::to_string(::getpid());
  const fs::path sub = source_submission(
      "cmake_hang", "execute_process(COMMAND sh -c \"" + sleep + "\" pinsim-hostile-cmake-hang)");
  const Graded g = grade(src / "rubric_build_hang.json", sub, "cmake_hang");
  CHECK(score(g) == 0);
  CHECK_THAT(g.results["tests"][0]["output"].get<std::string>(),
             Contains("the configure step did not finish within the wall-clock limit of 4 s"));
  CHECK(g.seconds < 20);
  CHECK(processes_with(sleep).empty());
}

TEST_CASE("hostile: a compiler error full of multi-byte characters, cut, stays valid text") {
  // 30,000 three-byte characters in the error: wherever the log is cut, it is mid-character
  // two times in three; the grader must still write valid UTF-8 and XML.
  std::string euros;
  for (int i = 0; i < 30000; ++i) euros += "\xE2\x82\xAC";
  const fs::path sub = source_submission("utf8_error", "", "#error \"" + euros + "\"\n");
  const Graded g = grade(hostile_rubric, sub, "utf8_error");
  CHECK(score(g) == 0);
  const std::string out = g.results["tests"][0]["output"].get<std::string>();
  CHECK_THAT(out, Contains("the submission does not compile"));
  CHECK_THAT(out, Contains("bytes not shown"));
}

TEST_CASE("hostile: one plugin that does not compile costs only its own tests") {
  const fs::path sub = source_submission(
      "partial",
      "file(WRITE ${CMAKE_BINARY_DIR}/damped.cpp \"#include <pinsim/plugin.hpp>\\nclass X { "
      "oops }\\n\")\npinsim_add_plugin(damped_spring ${CMAKE_BINARY_DIR}/damped.cpp)");
  const Graded g = grade(src / "rubric_two_plugins.json", sub, "partial");
  auto t = by_name(g.results);
  CHECK(t["linear_spring loads"]["status"] == "passed");
  CHECK(t["linear_spring f = -grad E"]["status"] == "passed");
  CHECK(t["damped_spring loads"]["status"] == "failed");
  CHECK_THAT(t["damped_spring loads"]["output"].get<std::string>(),
             Contains("the submission does not compile"));
  CHECK_THAT(t["damped_spring loads"]["output"].get<std::string>(), Contains("damped.cpp"));
  // Said once: the plugin's other test points to it.
  CHECK(t["damped_spring f = -grad E"]["output"] ==
        "not run: 'damped_spring' did not build, see test 3");
  CHECK(score(g) == 2);
}

TEST_CASE("hostile: without a sandbox the grader refuses, unless told to grade unsafely") {
  const fs::path plain = subs / "hostile_bad_text";  // any correct-physics library
  const Graded refused =
      grade(hostile_rubric, plain, "nosandbox", "", "PINSIM_BWRAP=/nonexistent/bwrap");
  CHECK(refused.exit_code == 2);
  CHECK(score(refused) == 0);
  CHECK_THAT(refused.results["output"].get<std::string>(), Contains("cannot isolate submissions"));
  CHECK_THAT(refused.results["output"].get<std::string>(), Contains("--unsafe-no-sandbox"));
  const Graded unsafe = grade(hostile_rubric, plain, "unsafe", "--unsafe-no-sandbox",
                              "PINSIM_BWRAP=/nonexistent/bwrap");
  CHECK(unsafe.exit_code == 0);
  CHECK(score(unsafe) == 7);
}

TEST_CASE("hostile: the submission's time budget stops tests that would start after it") {
  const Graded g = grade(src / "rubric_budget.json", hostile("sleep_in_create"), "budget");
  CHECK(score(g) == 1);  // loading passes, within the budget
  auto t = by_name(g.results);
  CHECK_THAT(t["f = -grad E"]["output"].get<std::string>(), Contains("wall-clock limit of 2 s"));
  for (const char* name : {"agrees with the reference", "hanging chain"})
    CHECK_THAT(t[name]["output"].get<std::string>(),
               Contains("not run: the submission used up its time budget of 1 s"));
}

TEST_CASE("hostile: a grader killed mid-way leaves valid files saying so, and no sandbox") {
  IN_EACH_SANDBOX();
  const fs::path out = pinsim::test::temp_dir("hostile-killed");
  const auto r = pinsim::test::shell(g_launcher + PINSIM_BIN + " -q grade --rubric " +
                                     (src / "rubric_hang.json").string() + " --submission " +
                                     hostile("sleep_in_create").string() + " --out " +
                                     out.string() + " > /dev/null 2>&1 & echo $!");
  const pid_t grader = std::stoi(r.output);
  // Every process below the grader (bubblewrap and the sandbox).
  auto processes_below = [&] {
    std::vector<pid_t> below;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator("/proc", ec)) {
      const std::string name = e.path().filename().string();
      if (name.empty() || !std::isdigit(static_cast<unsigned char>(name[0]))) continue;
      pid_t p = std::stoi(name);
      for (int depth = 0; depth < 10 && p > 1; ++depth) {
        const std::string stat = pinsim::test::read_file("/proc/" + std::to_string(p) + "/stat");
        const auto close = stat.rfind(')');
        if (close == std::string::npos) break;
        p = std::atoi(stat.c_str() + close + 4);  // ") S PPID"
        if (p == grader) {
          below.push_back(std::stoi(name));
          break;
        }
      }
    }
    return below;
  };
  // Test 2 sleeps in create for its 2 s limit: kill the grader in the middle of it, once
  // results.json holds test 1 and a sandbox runs (polled, so a loaded machine only delays
  // the kill; 60 s at most).
  std::vector<pid_t> below;
  for (int i = 0; i < 1200; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const json now = json::parse(pinsim::test::read_file(out / "results.json"), nullptr, false);
    if (now.is_object() && now.contains("tests") && now["tests"].size() == 1) {
      below = processes_below();
      if (!below.empty()) break;
    }
  }
  CHECK_FALSE(below.empty());  // the sandbox was running
  ::kill(grader, SIGKILL);
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  for (pid_t p : below) {
    // Gone, or a zombie: dead, waiting for an init that reaps (some containers have none).
    const std::string stat = pinsim::test::read_file("/proc/" + std::to_string(p) + "/stat");
    const auto close = stat.rfind(')');
    CAPTURE(p, stat);
    CHECK((stat.empty() || close == std::string::npos || stat[close + 2] == 'Z'));
  }
  check_files_valid(out);
  const json res = json::parse(pinsim::test::read_file(out / "results.json"));
  CHECK(res["score"].get<double>() == 0);
  CHECK_THAT(res["output"].get<std::string>(), Contains("Grading did not finish"));
  CHECK(res["tests"].size() == 1);  // the load test, finished before the kill
}

TEST_CASE("hostile: a rubric with an unknown key is refused, naming the JSON path") {
  const fs::path dir = pinsim::test::temp_dir("bad-rubric");
  pinsim::test::write_file(dir / "rubric.json",
                           R"({"name": "x", "kind": "force", "tests": [{"name": "a", "check": )"
                           R"("load", "plugin": "linear_spring", "pionts": 3}]})");
  const auto r = pinsim::test::shell(std::string(PINSIM_BIN) + " grade --rubric " +
                                     (dir / "rubric.json").string() + " --submission " +
                                     hostile("bad_text").string() + " --out " +
                                     (dir / "out").string() + " 2>&1");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("rubric.json: tests[0].pionts: unknown key"));
  check_files_valid(dir / "out");
  CHECK_THAT(pinsim::test::read_file(dir / "out/results.json"), Contains("rubric is invalid"));
}
