// SIGINT, SIGTERM, SIGHUP, SIGQUIT and the other stop signals (kStopSignals) during run, bench,
// stress and crosscheck: each finishes its current step or point, writes what is done and exits
// with 128 + the signal. Every test waits for a progress file before signalling, so it is not a
// race on a loaded machine.
#include <signal.h>
#include <sys/wait.h>

#include <catch2/catch.hpp>
#include <chrono>
#include <nlohmann/json.hpp>
#include <thread>

#include "test_support.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;
namespace fs = std::filesystem;

namespace {

bool has_bytes(const fs::path& p, std::uintmax_t n) {
  std::error_code ec;
  return fs::file_size(p, ec) >= n && !ec;
}

std::size_t csv_rows(const fs::path& p) {
  const std::string t = test::read_file(p);
  return static_cast<std::size_t>(std::count(t.begin(), t.end(), '\n')) - 1;  // minus the header
}

// The harmonic oscillator x'' = -9 x (omega = 3) over 50 s at 20 dt near 1e-4: 20 points of
// about 500,000 steps each, so the sweep is still running when its first point is on disk.
// `bench`: a bench config (closed-form answer); else a stress config (a stiffness case).
std::string oscillator_sweep(bool bench) {
  std::string dts;
  for (int i = 0; i < 20; ++i) dts += (i ? ", " : "") + std::to_string(1e-4 * (1.0 + 0.01 * i));
  const std::string scene = R"("scene": {"time": {"dt": 0.01, "duration": 50.0},
      "particles": [{"x": [0, 0], "pinned": true}, {"x": [1, 0], "v": [0, 1.5], "mass": 2.0}],
      "forces": [{"type": "linear_spring", "params": {"k": 18.0, "rest_length": 0.0},
                  "elements": [[0, 1]]}]}, "dt": [)" +
                            dts + "]";
  if (bench)
    return R"({"repeats": 1, "integrators": ["symplectic_euler"], "cases": [{"name": "osc",
      "answer": {"type": "harmonic", "particle": 1, "omega": 3.0}, )" +
           scene + "}]}";
  return R"({"energy_blowup": 100.0, "integrators": ["symplectic_euler"], "cases": [
      {"name": "osc", "kind": "stiffness",
       "stiffness": {"path": "forces[0].params.k", "values": [18]}, )" +
         scene + "}]}";
}

}  // namespace

TEST_CASE("signals: run stops after the current step with a summary saying so") {
  for (const int sig :
       {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGPIPE, SIGUSR1, SIGUSR2, SIGALRM, SIGVTALRM, SIGXCPU}) {
    CAPTURE(sig);
    const fs::path dir = test::temp_dir("sig-run");
    const fs::path out = dir / "run";
    test::write_file(dir / "long.json", R"({"time": {"dt": 0.001, "duration": 100000.0},
      "particles": [{"x": [0, 0], "v": [1, 0]}], "forces": [{"type": "gravity"}],
      "output": {"every": 10}})");
    const pid_t pid = test::spawn_pinsim(
        {"run", (dir / "long.json").string(), "--out", out.string()}, dir / "log");
    REQUIRE(test::wait_until([&] { return has_bytes(out / "trajectory.csv", 4096); }));
    ::kill(pid, sig);
    CHECK(test::wait_pinsim(pid) == 128 + sig);
    const auto s = nlohmann::json::parse(test::read_file(out / "summary.json"));
    const std::string name = s["signal"]["name"].get<std::string>();
    CHECK(name == (sig == SIGINT      ? "SIGINT"
                   : sig == SIGTERM   ? "SIGTERM"
                   : sig == SIGHUP    ? "SIGHUP"
                   : sig == SIGQUIT   ? "SIGQUIT"
                   : sig == SIGPIPE   ? "SIGPIPE"
                   : sig == SIGUSR1   ? "SIGUSR1"
                   : sig == SIGUSR2   ? "SIGUSR2"
                   : sig == SIGALRM   ? "SIGALRM"
                   : sig == SIGVTALRM ? "SIGVTALRM"
                                      : "SIGXCPU"));
    CHECK(s["status"] == "interrupted");
    CHECK(s["signal"]["number"] == sig);
    CHECK(s["steps"].get<long>() > 0);
    CHECK(s["steps"].get<long>() < 100000000);
    const std::string traj = test::read_file(out / "trajectory.csv");
    CHECK(traj.back() == '\n');
    CHECK_THAT(test::read_file(dir / "log"), Contains("stopped by " + name + " after step " +
                                                      std::to_string(s["steps"].get<long>())));
  }
}

TEST_CASE("signals: a second signal during a stuck step ends run with its summary written") {
  // The fixture force sleeps 60 s in step 52 (x = 0.51 after step 51 passes 0.505, as in the
  // crash test), so the first SIGINT cannot end the step: the run is stuck in it, and a
  // second SIGINT ends the process. Its summary must say so, not stay at "running".
  const fs::path dir = test::temp_dir("sig-second");
  const fs::path out = dir / "run";
  test::write_file(dir / "stuck.json", R"({"time": {"dt": 0.01, "duration": 2.0},
    "particles": [{"x": [0, 0], "v": [1, 0]}],
    "forces": [{"type": "crash_force", "library": ")" PINSIM_TEST_FIXTURE_DIR
                                       R"(/libfixture_crash_force.so",
                "params": {"threshold": 0.505, "stall_s": 60}}],
    "output": {"every": 1}})");
  const pid_t pid = test::spawn_pinsim(
      {"run", (dir / "stuck.json").string(), "--out", out.string()}, dir / "log");
  // The initial state and steps 1..51 are on disk (52 rows): the run is in step 52.
  REQUIRE(test::wait_until([&] {
    return has_bytes(out / "trajectory.csv", 1) && csv_rows(out / "trajectory.csv") >= 52;
  }));
  // SIGINT until the process is gone: the first only asks it to stop (the step does not
  // end), a later one ends it. Sent 100 ms apart, so two are never pending at once.
  int status = 0, sent = 0;
  pid_t done = 0;
  while ((done = ::waitpid(pid, &status, WNOHANG)) == 0 && sent < 100) {
    ::kill(pid, SIGINT);
    ++sent;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  if (done == 0) done = ::waitpid(pid, &status, 0);
  REQUIRE(done == pid);
  CHECK(WIFSIGNALED(status));
  CHECK(WTERMSIG(status) == SIGINT);
  CHECK(sent >= 2);
  const auto s = nlohmann::json::parse(test::read_file(out / "summary.json"));
  CHECK(s["status"] == "interrupted");
  CHECK(s["steps"] == 51);
  CHECK(s["signal"]["name"] == "SIGINT");
  CHECK(s["signal"]["number"] == SIGINT);
  CHECK(s["error"]["kind"] == "signal");
  CHECK(s["error"]["step"] == 52);
  CHECK(s["error"]["message"] == "the process was ended by a second SIGINT during step 52");
  CHECK(csv_rows(out / "trajectory.csv") == 52);
}

TEST_CASE("signals: bench keeps its finished points and --continue goes on from them") {
  const fs::path dir = test::temp_dir("sig-bench");
  test::write_file(dir / "bench.json", oscillator_sweep(true));
  const fs::path out = dir / "out";
  const std::vector<std::string> args = {"bench", (dir / "bench.json").string(), "--out",
                                         out.string()};
  const pid_t pid = test::spawn_pinsim(args, dir / "log");
  REQUIRE(test::wait_until([&] { return fs::exists(out / "bench.partial.json"); }));
  ::kill(pid, SIGTERM);
  CHECK(test::wait_pinsim(pid) == 143);
  CHECK_FALSE(fs::exists(out / "bench.csv"));
  const std::size_t done = csv_rows(out / "bench.partial.csv");
  CHECK(done >= 1);
  CHECK(done < 20);
  const auto m = nlohmann::json::parse(test::read_file(out / "bench.partial.json"));
  CHECK(m["rows"] == done);
  CHECK(m["points"] == 20);
  CHECK_THAT(test::read_file(dir / "log"),
             Contains("stopped by SIGTERM after " + std::to_string(done) +
                      " of this shard's 20 points; the finished points are in " +
                      (out / "bench.partial.csv").string()) &&
                 Contains("continue with: pinsim bench " + (dir / "bench.json").string() +
                          " --out " + out.string() + " --continue"));

  // --continue runs only the points not done; the whole table ends up in bench.csv.
  auto resumed = args;
  resumed.push_back("--continue");
  const pid_t again = test::spawn_pinsim(resumed, dir / "log2");
  CHECK(test::wait_pinsim(again) == 0);
  CHECK_THAT(
      test::read_file(dir / "log2"),
      Contains("resuming: " + std::to_string(done) + " of this shard's 20 points already done") &&
          Contains("this shard (0/1) runs " + std::to_string(20 - done)));
  CHECK(csv_rows(out / "bench.csv") == 20);
  CHECK_FALSE(fs::exists(out / "bench.partial.csv"));
  CHECK_FALSE(fs::exists(out / "bench.partial.json"));
}

TEST_CASE("signals: stress on SIGINT keeps its finished points") {
  const fs::path dir = test::temp_dir("sig-stress");
  test::write_file(dir / "stress.json", oscillator_sweep(false));
  const fs::path out = dir / "out";
  const pid_t pid = test::spawn_pinsim(
      {"stress", (dir / "stress.json").string(), "--out", out.string(), "--shard", "1/2"},
      dir / "log");
  const fs::path partial = out / "stress.partial.shard-1-of-2.csv";
  REQUIRE(test::wait_until([&] { return fs::exists(out / "stress.partial.shard-1-of-2.json"); }));
  ::kill(pid, SIGINT);
  CHECK(test::wait_pinsim(pid) == 130);
  const std::size_t done = csv_rows(partial);
  CHECK(done >= 1);
  CHECK(done < 10);
  CHECK_FALSE(fs::exists(out / "stress.shard-1-of-2.csv"));
  CHECK_THAT(
      test::read_file(dir / "log"),
      Contains("stopped by SIGINT after " + std::to_string(done) + " of this shard's 10 points") &&
          Contains(" --shard 1/2 --continue"));
}

TEST_CASE("signals: crosscheck stops its run and writes a report saying how far it got") {
  const fs::path dir = test::temp_dir("sig-cc");
  const fs::path out = dir / "out";
  const pid_t pid =
      test::spawn_pinsim({"crosscheck", PINSIM_SOURCE_DIR "/configs/crosscheck/wall.json", "--set",
                          "time.duration=2000", "--out", out.string()},
                         dir / "log");
  REQUIRE(test::wait_until(
      [&] { return Contains("running on sdf").match(test::read_file(dir / "log")); }));
  ::kill(pid, SIGHUP);
  CHECK(test::wait_pinsim(pid) == 129);
  const auto r = nlohmann::json::parse(test::read_file(out / "report.json"));
  CHECK(r["status"] == "interrupted");
  CHECK(r["signal"] == nlohmann::json{{"name", "SIGHUP"}, {"number", 1}});
  CHECK(r["steps"] == 2000000);
  REQUIRE(r["runs"].size() == 2);
  CHECK(r["runs"][0]["backend"] == "sdf");
  CHECK(r["runs"][0]["steps_done"].get<long>() < 2000000);
  CHECK(r["runs"][1]["steps_done"] == 0);
  CHECK_THAT(test::read_file(dir / "log"), Contains("crosscheck interrupted by SIGHUP"));
}
