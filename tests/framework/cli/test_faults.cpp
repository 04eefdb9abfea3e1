// Faults around `pinsim run`: a full disk or a file-size limit, a crashing plugin, and
// --overwrite over an earlier run's folder. Each checks the exit status, the message and
// that every file left behind is whole.
#include <signal.h>
#include <stdlib.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "test_support.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;
using Catch::Matchers::EndsWith;
namespace fs = std::filesystem;

namespace {

// One particle falling for 1000 s with a row every step: far more output than the limits
// below allow.
const std::string kLongScene = R"({"time": {"dt": 0.001, "duration": 1000.0},
  "particles": [{"x": [0, 0], "v": [1, 0]}], "forces": [{"type": "gravity"}],
  "output": {"every": 1}})";

// Under ASan (the asan preset) a child must leave the crash signals to pinsim's own handler
// and then to the default action, as a release build does: ASan would otherwise report the
// crash and exit 1. The options are read when the child starts; this process's sanitizer
// read its own long ago. (Without ASan the variable is ignored.)
void leave_crash_signals_to_pinsim() {
  const char* own = std::getenv("ASAN_OPTIONS");
  ::setenv("ASAN_OPTIONS",
           ((own && *own ? std::string(own) + ":" : std::string()) +
            "handle_segv=0:handle_sigbus=0:handle_sigfpe=0:handle_sigill=0:handle_abort=0")
               .c_str(),
           1);
}

// Every line of a CSV file is whole: the file ends with '\n', each line has `commas`, and
// there are at least `min_lines`.
void check_whole_lines(const fs::path& csv, int commas, std::size_t min_lines = 2) {
  const std::string text = test::read_file(csv);
  REQUIRE_FALSE(text.empty());
  CHECK(text.back() == '\n');
  std::size_t start = 0, lines = 0;
  while (start < text.size()) {
    const std::size_t end = text.find('\n', start);
    REQUIRE(end != std::string::npos);
    CHECK(std::count(text.begin() + static_cast<long>(start), text.begin() + static_cast<long>(end),
                     ',') == commas);
    start = end + 1;
    ++lines;
  }
  CHECK(lines >= min_lines);
}

}  // namespace

TEST_CASE("faults: run at a file-size limit exits 1 naming the file, lines whole") {
  const fs::path dir = test::temp_dir("fsize");
  test::write_file(dir / "long.json", kLongScene);
  const fs::path out = dir / "run";
  // RLIMIT_FSIZE of 100,000 bytes: trajectory.csv reaches it first (about 1,700 rows).
  const auto r = test::shell("prlimit --fsize=100000 " PINSIM_BIN " run " +
                             (dir / "long.json").string() + " --out " + out.string());
  CAPTURE(r.output);
  CHECK(r.code == 1);
  CHECK_THAT(r.output,
             Contains((out / "trajectory.csv").string() + ": cannot write (File too large)") &&
                 Contains("the files keep every whole line written before"));
  CHECK(fs::file_size(out / "trajectory.csv") <= 100000);
  CHECK(fs::file_size(out / "trajectory.csv") > 50000);
  check_whole_lines(out / "trajectory.csv", 5);
  check_whole_lines(out / "events.csv", 9, 1);
  const auto s = nlohmann::json::parse(test::read_file(out / "summary.json"));
  CHECK(s["status"] == "error");
  CHECK(s["error"]["kind"] == "output");
  CHECK_THAT(s["error"]["message"].get<std::string>(),
             Contains("trajectory.csv: cannot write (File too large)"));
  CHECK(s["steps"].get<int>() > 1000);
  CHECK(s["steps"].get<int>() < 2000);
  // No temporary file is left.
  for (const auto& e : fs::directory_iterator(out))
    CHECK_THAT(e.path().filename().string(), !Contains(".tmp.") && !Contains(".crash."));
}

TEST_CASE("faults: run on a full disk (a 256 KiB tmpfs) exits 1, summary parses") {
  if (::geteuid() != 0) {
    WARN("not root: no tmpfs can be mounted; the file-size limit test covers the same path");
    return;
  }
  const fs::path dir = test::temp_dir("fulldisk");
  test::write_file(dir / "long.json", kLongScene);
  const fs::path mnt = dir / "mnt", copy = dir / "copy";
  fs::create_directories(mnt);
  fs::create_directories(copy);
  // A private mount namespace: the tmpfs disappears with the shell; its files are copied out.
  const std::string script = "mount -t tmpfs -o size=256k tmpfs " + mnt.string() +
                             " || exit 99; " PINSIM_BIN " run " + (dir / "long.json").string() +
                             " --out " + (mnt / "run").string() + "; echo \"rc=$?\"; cp " +
                             (mnt / "run").string() + "/* " + copy.string();
  const auto r = test::shell("unshare --mount sh -c '" + script + "'");
  CAPTURE(r.output);
  if (r.code != 0 && !Contains("rc=").match(r.output)) {
    WARN("cannot mount a tmpfs here (no CAP_SYS_ADMIN?): " + r.output);
    return;
  }
  CHECK_THAT(r.output, Contains((mnt / "run" / "trajectory.csv").string() +
                                ": cannot write (No space left on device)") &&
                           Contains("rc=1"));
  // tmpfs has no room for a new summary.json either: it goes into the space reserved for it
  // at the start.
  CHECK_THAT(r.output, Contains("summary.json written into the space reserved for it"));
  check_whole_lines(copy / "trajectory.csv", 5);
  const auto s = nlohmann::json::parse(test::read_file(copy / "summary.json"));
  CHECK(s["status"] == "error");
  CHECK(s["error"]["kind"] == "output");
  CHECK_THAT(s["error"]["message"].get<std::string>(),
             Contains("trajectory.csv: cannot write (No space left on device)"));
}

TEST_CASE("faults: a crashing force plugin leaves summary.json saying crashed") {
  // The ball moves at 1 unit/s with dt = 0.01: x = 0.51 after step 51, the first past the
  // fixture's threshold 0.505, so the force of step 52 crashes; 51 steps are complete.
  leave_crash_signals_to_pinsim();
  for (const int sig : {SIGSEGV, SIGABRT, SIGBUS, SIGFPE}) {
    CAPTURE(sig);
    const fs::path dir = test::temp_dir("crash");
    test::write_file(dir / "crash.json", R"({"time": {"dt": 0.01, "duration": 2.0},
      "particles": [{"x": [0, 0], "v": [1, 0]}],
      "forces": [{"type": "crash_force", "library": ")" PINSIM_TEST_FIXTURE_DIR
                                         R"(/libfixture_crash_force.so",
                  "params": {"signal": )" + std::to_string(sig) +
                                             R"(, "threshold": 0.505}}],
      "output": {"every": 1}})");
    const pid_t pid = test::spawn_pinsim(
        {"run", (dir / "crash.json").string(), "--out", (dir / "run").string()}, dir / "log");
    CHECK(test::wait_pinsim(pid) == -sig);  // the signal still kills the process
    const auto s = nlohmann::json::parse(test::read_file(dir / "run" / "summary.json"));
    CHECK(s["status"] == "crashed");
    CHECK(s["steps"] == 51);
    CHECK(s["signal"]["number"] == sig);
    CHECK(s["signal"]["name"] == (sig == SIGSEGV   ? "SIGSEGV"
                                  : sig == SIGABRT ? "SIGABRT"
                                  : sig == SIGBUS  ? "SIGBUS"
                                                   : "SIGFPE"));
    CHECK(s["error"]["kind"] == "crash");
    CHECK(s["error"]["step"] == 52);
    CHECK(s["error"]["message"] == "the process was killed by " +
                                       s["signal"]["name"].get<std::string>() + " during step 52");
    CHECK(s["scene"] == (dir / "crash.json").string());
    CHECK(s["backend"] == "none");
    check_whole_lines(dir / "run" / "trajectory.csv", 5);
    for (const auto& e : fs::directory_iterator(dir / "run"))
      CHECK_THAT(e.path().filename().string(), !Contains(".crash."));
    // summary.json says it, so the notice of a crash with no summary stays silent.
    CHECK_THAT(test::read_file(dir / "log"), !Contains("pinsim: killed by"));
  }
}

TEST_CASE("faults: a plugin that crashes before the output folder is prepared says so") {
  // The fixture crashes in its constructor, before run_scene arms the crash summary: no
  // summary.json can say it, so stderr does, and the signal still kills the process.
  leave_crash_signals_to_pinsim();
  for (const int sig : {SIGSEGV, SIGABRT}) {
    for (const bool out : {true, false}) {
      CAPTURE(sig, out);
      const fs::path dir = test::temp_dir("crash-early");
      test::write_file(dir / "crash.json", R"({"time": {"dt": 0.01, "duration": 1.0},
        "particles": [{"x": [0, 0], "v": [1, 0]}],
        "forces": [{"type": "crash_force", "library": ")" PINSIM_TEST_FIXTURE_DIR
                                           R"(/libfixture_crash_force.so",
                    "params": {"signal": )" + std::to_string(sig) +
                                               R"(, "in_create": true}}]})");
      std::vector<std::string> args = {"run", (dir / "crash.json").string()};
      if (out) args.insert(args.end(), {"--out", (dir / "run").string()});
      const pid_t pid = test::spawn_pinsim(args, dir / "log");
      CHECK(test::wait_pinsim(pid) == -sig);
      const std::string name = sig == SIGSEGV ? "SIGSEGV" : "SIGABRT";
      const std::string log = test::read_file(dir / "log");
      CHECK_THAT(log, Contains("pinsim: killed by " + name +
                               (out ? " before the run's output folder was prepared: it has no "
                                      "summary.json"
                                    : " (a run without --out writes no summary.json)")));
      CHECK_FALSE(fs::exists(dir / "run" / "summary.json"));
    }
  }
}

TEST_CASE("faults: --overwrite removes the earlier run's files, keeps the user's") {
  const fs::path dir = test::temp_dir("overwrite");
  const std::string scene = PINSIM_SOURCE_DIR "/configs/projectile.json";
  auto r = test::pinsim_cli("-q run " + scene + " --out " + dir.string());
  REQUIRE(r.code == 0);
  for (const char* f :
       {"picture.png", "replay.html", "summary.json.tmp.1234", "notes.txt", "picture.png.bak"})
    test::write_file(dir / f, "from before\n");
  fs::create_directories(dir / "plots");
  r = test::pinsim_cli("-q run " + scene + " --out " + dir.string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("holds an earlier run (trajectory.csv); choose another --out or "
                                "pass --overwrite"));
  CHECK(fs::exists(dir / "picture.png"));
  r = test::pinsim_cli("-q run " + scene + " --out " + dir.string() + " --overwrite");
  CHECK(r.code == 0);
  CHECK_FALSE(fs::exists(dir / "picture.png"));
  CHECK_FALSE(fs::exists(dir / "replay.html"));
  CHECK_FALSE(fs::exists(dir / "summary.json.tmp.1234"));
  CHECK(test::read_file(dir / "notes.txt") == "from before\n");
  CHECK(test::read_file(dir / "picture.png.bak") == "from before\n");
  CHECK(fs::is_directory(dir / "plots"));
  for (const char* f : {"trajectory.csv", "events.csv", "summary.json", "scene.json"})
    CHECK(fs::exists(dir / f));
  CHECK(nlohmann::json::parse(test::read_file(dir / "summary.json"))["status"] == "ok");
}

TEST_CASE("faults: render and replay write their file whole or say why, exit 1") {
  const fs::path dir = test::temp_dir("pictures");
  REQUIRE(test::pinsim_cli("-q run " PINSIM_SOURCE_DIR "/configs/projectile.json --out " +
                           (dir / "run").string())
              .code == 0);
  // A folder where the file should go: the rename at the end fails, nothing half is left.
  for (const char* f : {"p.png", "p.svg", "r.html"}) fs::create_directories(dir / f);
  for (const std::string f : {"p.png", "p.svg"}) {
    const auto r =
        test::pinsim_cli("-q render " + (dir / "run").string() + " --out " + (dir / f).string());
    CHECK(r.code == 1);
    CHECK_THAT(r.output, Contains((dir / f).string() + ": cannot write (Is a directory)"));
  }
  const auto r = test::pinsim_cli("-q replay " + (dir / "run").string() + " --out " +
                                  (dir / "r.html").string());
  CHECK(r.code == 1);
  CHECK_THAT(r.output, Contains((dir / "r.html").string() + ": cannot write (Is a directory)"));
  for (const auto& e : fs::directory_iterator(dir))
    CHECK_THAT(e.path().filename().string(), !Contains(".tmp."));
  // And written whole when they can be.
  CHECK(test::pinsim_cli("-q render " + (dir / "run").string()).code == 0);
  CHECK(test::read_file(dir / "run" / "picture.png").rfind("\x89PNG", 0) == 0);
}
