// The pinsim program itself: exit codes and one-line errors for bad input.
#include <sys/wait.h>

#include <catch2/catch.hpp>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "test_support.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;

namespace {

using test::pinsim_cli;

const std::string configs = PINSIM_SOURCE_DIR "/configs";

}  // namespace

TEST_CASE("cli: --version") {
  const auto r = pinsim_cli("--version");
  CHECK(r.code == 0);
  CHECK_THAT(r.output, Contains("pinsim " PINSIM_VERSION));
}

TEST_CASE("cli: plugins lists the in-tree plugins and shows a parameter table") {
  auto r = pinsim_cli("plugins");
  CHECK(r.code == 0);
  CHECK_THAT(r.output, Contains("gravity") && Contains("none"));
  r = pinsim_cli("plugins gravity");
  CHECK(r.code == 0);
  CHECK_THAT(r.output, Contains("parameters:") && Contains("m/s^2") && Contains("[0.0,-9.81]"));
  // what pinsim grad can take of it: the parameter derivatives and products (ABI 4.4, 4.5),
  // and which parameters are differentiable (g and G, not alpha)
  CHECK_THAT(r.output, Contains("dparam jacobian-products adjoint-products"));
  std::istringstream lines(r.output);
  for (std::string l; std::getline(lines, l);) {
    INFO(l);
    if (l.rfind("    g ", 0) == 0 || l.rfind("    G ", 0) == 0)
      CHECK_THAT(l, Contains("differentiable"));
    if (l.rfind("    alpha ", 0) == 0) CHECK_THAT(l, !Contains("differentiable"));
  }
}

TEST_CASE("cli: plugins gives units to quantities only") {
  // gravity's "mode" is a string choice: no units; its "g" is an acceleration in m/s^2.
  const auto r = pinsim_cli("plugins gravity");
  REQUIRE(r.code == 0);
  std::string mode_line;
  std::istringstream lines(r.output);
  for (std::string l; std::getline(lines, l);)
    if (l.find(" mode ") != std::string::npos) mode_line = l;
  INFO(r.output);
  REQUIRE_THAT(mode_line, Contains("one of uniform|pairwise"));
  CHECK(mode_line.find('[') == std::string::npos);
  CHECK_THAT(r.output, Contains("[m/s^2]"));
}

TEST_CASE("cli: plugins --plugin-path lists and loads a plugin from that folder") {
  // The fixture folder holds libpinsim_plugin_ring_area_pairs.so, on no default search path.
  auto r = pinsim_cli("plugins ring_area_pairs");
  CHECK(r.code == 2);
  r = pinsim_cli(std::string("plugins ring_area_pairs --plugin-path ") + PINSIM_TEST_FIXTURE_DIR);
  INFO(r.output);
  CHECK(r.code == 0);
  CHECK_THAT(r.output, Contains("parameters:"));
  r = pinsim_cli(std::string("plugins --plugin-path ") + PINSIM_TEST_FIXTURE_DIR);
  CHECK(r.code == 0);
  CHECK_THAT(r.output, Contains("ring_area_pairs") && Contains(PINSIM_TEST_FIXTURE_DIR));
}

TEST_CASE("cli: run writes output and validate accepts a good scene") {
  const auto dir = test::temp_dir("cli");
  auto r = pinsim_cli("-q run " + configs + "/projectile.json --out " + dir.string());
  CHECK(r.code == 0);
  CHECK(r.output.empty());
  CHECK(test::read_file(dir / "trajectory.csv").rfind("t,particle,x,y,vx,vy\n", 0) == 0);
  r = pinsim_cli("validate " + configs + "/projectile.json");
  CHECK(r.code == 0);
  CHECK_THAT(r.output, Contains("ok: 1 particles"));
}

TEST_CASE("cli: the global -q and -v are taken after the subcommand too") {
  const auto dir = test::temp_dir("cli-q-after");
  auto r = pinsim_cli("run " + configs + "/projectile.json --out " + dir.string() + " -q");
  CHECK(r.code == 0);
  CHECK(r.output.empty());  // without -q: "[info] ... ok after ..."
  r = pinsim_cli("run " + configs + "/projectile.json --out " + dir.string() + " --overwrite");
  CHECK(r.code == 0);
  CHECK_THAT(r.output, Contains("[info]"));
  r = pinsim_cli("validate " + configs + "/projectile.json -v");
  CHECK(r.code == 0);
  CHECK_THAT(r.output, Contains("ok: 1 particles"));
}

TEST_CASE("cli: --set, --integrator and --backend reach the run") {
  const auto dir = test::temp_dir("cli-set");
  const auto r = pinsim_cli("-q run " + configs + "/projectile.json --set time.duration=0.5 " +
                            "--integrator velocity_verlet --backend none --out " + dir.string());
  CHECK(r.code == 0);
  const auto s = nlohmann::json::parse(test::read_file(dir / "summary.json"));
  CHECK(s["steps"] == 500);
  CHECK(s["integrator"] == "velocity_verlet");
}

TEST_CASE("cli: --backend box2d on the pinball table uses the scene's crosscheck.params.box2d") {
  // The table's round top needs box2d's curve_segments, which the scene gives only in
  // crosscheck.params.box2d; before, --backend dropped them and the run failed.
  const auto dir = test::temp_dir("cli-box2d");
  auto r = pinsim_cli("run " + configs + "/pinball.json --backend box2d --out " + dir.string());
  INFO(r.output);
  CHECK(r.code == 0);
  CHECK_THAT(r.output, Contains("--backend box2d: using the scene's crosscheck.params.box2d") &&
                           Contains("\"curve_segments\":256"));
  auto s = nlohmann::json::parse(test::read_file(dir / "summary.json"));
  CHECK(s["backend"] == "box2d");
  CHECK(s["status"] == "ok");
  // --set after --backend sets the chosen backend's parameters (scene.json is the scene as
  // run); here a coarser round top, on a short run.
  const auto dir2 = test::temp_dir("cli-box2d-set");
  r = pinsim_cli("-q run " + configs + "/pinball.json --backend box2d --set " +
                 "backend.params.curve_segments=64 --set time.duration=0.5 --out " + dir2.string());
  CHECK(r.code == 0);
  const auto ran = nlohmann::json::parse(test::read_file(dir2 / "scene.json"));
  CHECK(ran["backend"]["name"] == "box2d");
  CHECK(ran["backend"]["params"]["curve_segments"] == 64);
  CHECK(ran["backend"]["params"]["rest_speed"] == 0.005);  // the rest from crosscheck.params
}

TEST_CASE("cli: crosscheck's contact table explains e; an unresolved contact is open, not -1") {
  // On the pinball table the ball rolls along box2d's segments of the round top: a contact
  // ended by the next one in the same step keeps vn_after = vn_before, so e = -vn_after /
  // vn_before would read -1. It is shown as 'open' with null restitution in report.json.
  const auto dir = test::temp_dir("cli-crosscheck-e");
  const auto r = pinsim_cli("crosscheck " + configs + "/pinball.json --out " + dir.string());
  INFO(r.output);
  const auto report = nlohmann::json::parse(test::read_file(dir / "report.json"));
  int open = 0;
  for (const auto& p : report["particles"])
    for (const auto& c : p["contacts"])
      for (const char* b : {"sdf", "box2d"}) {
        if (!c.contains(b) || c[b].is_null()) continue;
        const auto& e = c[b];
        if (e["vn_before"].get<double>() < 0 && e["vn_after"] == e["vn_before"]) {
          ++open;
          CHECK(e["restitution"].is_null());
        } else if (!e["restitution"].is_null()) {
          CHECK(e["restitution"].get<double>() >= 0.0);
        }
      }
  CHECK(open > 0);
  const std::string table = test::read_file(dir / "report.txt");
  CHECK_THAT(table, Contains("   open |") && Contains("e = -vn_after / vn_before"));
  CHECK(table.find("-1.000 |") == std::string::npos);
}

TEST_CASE("cli: bad input gives one error line and a non-zero exit") {
  const auto dir = test::temp_dir("cli-bad");
  test::write_file(dir / "broken.json", "{ \"time\": ");
  test::write_file(dir / "a_file", "x");
  const std::pair<std::string, std::string> cases[] = {
      {"run " + dir.string() + "/missing.json", "missing.json: scene file not found"},
      {"run " + dir.string() + "/broken.json", "broken.json:1:"},
      {"run " + configs + "/projectile.json --set time.dt=0", "time.dt: must be > 0"},
      {"run " + configs + "/projectile.json --set time.duration=-1", "time.duration: must be >= 0"},
      {"run " + configs + "/projectile.json --set particles[0].mass=0",
       "particles[0].mass: must be > 0"},
      {"run " + configs + "/projectile.json --backend nowhere", "unknown plugin 'nowhere'"},
      {"run " + configs + "/projectile.json --integrator rk99", "unknown integrator 'rk99'"},
      {"run " + configs + "/projectile.json --out " + dir.string() + "/a_file/sub",
       "cannot create output folder"},
      {"plugins no_such_plugin", "unknown plugin 'no_such_plugin'"},
  };
  for (const auto& [args, expected] : cases) {
    CAPTURE(args);
    const auto r = pinsim_cli(args);
    CHECK(r.code == 2);
    CHECK_THAT(r.output, Contains("[error]") && Contains(expected));
    CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 1);
  }
}

TEST_CASE("cli: share --source names the folder or the web SDK it cannot use") {
  // Refused before Emscripten is started, so this needs no web build: a stand-in web SDK
  // (only its package file) and a stand-in engine.
  const auto dir = test::temp_dir("cli-share-source");
  test::write_file(dir / "sdk" / "cmake" / "pinsimConfig.cmake", "# stand-in\n");
  test::write_file(dir / "not_a_plugin" / "notes.txt", "x");
  test::write_file(dir / "plugin" / "CMakeLists.txt", "# stand-in\n");
  const std::string env = "PINSIM_WEB_SDK=" + (dir / "sdk").string() + " ";
  const std::string share = " " PINSIM_BIN " -q share " + configs + "/pinball.json --out " +
                            (dir / "page.html").string() + " --source ";
  struct Case {
    std::string command;
    int code;
    std::string expected;
  };
  const Case cases[] = {
      {env + share + (dir / "missing").string(), 2, "missing: no such folder"},
      {env + share + (dir / "not_a_plugin").string(), 2,
       "not_a_plugin: no CMakeLists.txt (a plugin folder"},
      {"PINSIM_WEB_SDK=" + (dir / "not_a_plugin").string() + share + (dir / "plugin").string(), 2,
       "not_a_plugin has no cmake/pinsimConfig.cmake"},
  };
  for (const auto& c : cases) {
    CAPTURE(c.command);
    const auto r = test::shell(c.command + " 2>&1");
    CHECK(r.code == c.code);
    CHECK_THAT(r.output, Contains("[error]") && Contains(c.expected));
  }
  CHECK_FALSE(std::filesystem::exists(dir / "page.html"));
}

TEST_CASE("cli: a flag the parser refuses is exit 2, naming the flag and what it expects") {
  // Values CLI11 checks itself (a range, a number) are bad input like an InputError.
  auto r = pinsim_cli("render " + configs + "/projectile.json --width 10");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("--width") && Contains("Value 10 not in range 64 to 8192"));
  r = pinsim_cli("run " + configs + "/projectile.json --no-such-flag");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("--no-such-flag"));
  r = pinsim_cli("run --help");
  CHECK(r.code == 0);
}

TEST_CASE("cli: every shipped scene in configs/ validates and runs to ok with the checks") {
  // The default numeric checks (finite state and the kinetic energy growth bound every step,
  // the total energy every 100 steps) must never stop a shipped scene.
  const auto dir = test::temp_dir("cli-shipped");
  int n = 0;
  for (const std::string sub : {"", "/crosscheck", "/grading/scenes"}) {
    for (const auto& e : std::filesystem::directory_iterator(configs + sub)) {
      const std::string name = e.path().filename().string();
      if (e.path().extension() != ".json" || name.ends_with(".schema.json")) continue;
      CAPTURE(e.path().string());
      auto r = pinsim_cli("validate " + e.path().string());
      CHECK(r.code == 0);
      CHECK_THAT(r.output, Contains(": ok:"));
      r = pinsim_cli("-q run " + e.path().string() + " --overwrite --out " + dir.string());
      CHECK(r.code == 0);
      const auto s = nlohmann::json::parse(test::read_file(dir / "summary.json"));
      CHECK(s["status"] == "ok");
      ++n;
    }
  }
  CHECK(n >= 20);
}
