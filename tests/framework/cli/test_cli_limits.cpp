// Bad input at the limits, through the program: command-line mistakes, values whose
// arithmetic would overflow, the backends' own preconditions, corrupt plugin files,
// views that would hang cairo, sizes. Each is exit 2 (nothing ran) with a message naming
// the file, the JSON path or option, and the limit; a failure during a run is exit 1.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "test_support.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;

namespace {

using test::pinsim_cli;

const std::string configs = PINSIM_SOURCE_DIR "/configs";

/// Runs `args` and checks exit status 2 with one "[error]" line containing `expected`.
void check_bad_input(const std::string& args, const std::string& expected) {
  CAPTURE(args);
  const auto r = pinsim_cli(args);
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("[error]") && Contains(expected));
  CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 1);
}

/// A one-ball scene on `backend` around `obstacles` (JSON), written to dir/name.
std::string write_scene(const std::filesystem::path& dir, const std::string& name,
                        const std::string& backend, const std::string& ball,
                        const std::string& obstacles = "[]") {
  const auto file = dir / name;
  test::write_file(file, R"({"time": {"dt": 0.01, "duration": 0.1}, "backend": ")" + backend +
                             R"(", "particles": [)" + ball + R"(], "obstacles": )" + obstacles +
                             "}");
  return file.string();
}

const std::string kBall = R"({"x": [0, 0], "v": [1, 0], "radius": 0.05})";
const std::string kWall =
    R"([{"id": "wall", "shape": {"type": "box", "center": [2, 0], "half_size": [0.1, 1]}}])";

}  // namespace

TEST_CASE("limits: every command-line mistake is exit 2 with CLI11's message") {
  check_bad_input("run --no-such-option", "--no-such-option");
  check_bad_input("", "A subcommand is required");
  check_bad_input("render", "inputs is required");
  check_bad_input("render x.json --width 10", "--width");
  check_bad_input("render x.json --width wide", "--width");
  check_bad_input("run a.json b.json", "b.json");
  const auto help = pinsim_cli("run --help");
  CHECK(help.code == 0);
  CHECK_THAT(help.output, Contains("--out"));
}

TEST_CASE("limits: masses, speeds, positions and parameters that overflow are refused") {
  const std::string p = "validate " + configs + "/projectile.json --set ";
  check_bad_input(p + "particles[0].mass=1e-320",
                  "projectile.json: particles[0].mass: must be between 1e-50 and 1e+50 (so that "
                  "1/m and m v^2 stay finite), got 1e-320");
  check_bad_input(p + "particles[0].mass=1e300", "particles[0].mass: must be between 1e-50");
  check_bad_input(p + "'particles[0].v=[2e154,0]'",
                  "projectile.json: particles[0].v[0]: velocity 2e+154 is beyond the limit of "
                  "1e+50 in magnitude (so that squares and energies stay finite)");
  check_bad_input(p + "'particles[0].x=[0,-1e200]'",
                  "projectile.json: particles[0].x[1]: coordinate -1e+200 is beyond the limit "
                  "of 1e+50");
  check_bad_input(p + "particles[0].radius=1e308",
                  "particles[0].radius: must be between 0 and 1e+50, got 1e+308");
  check_bad_input(p + "'forces[0].params.g=[0,-1e300]'",
                  "forces[0].params.g[1]: -1e+300 is beyond the limit of 1e+100 in magnitude "
                  "for a real parameter");
  check_bad_input(
      p + "'bodies=[{\"type\":\"ring_blob\",\"center\":[1e60,0],\"count\":4}]'",
      "projectile.json: bodies[0]: puts its particle 0 at (1e+60, 0), beyond the coordinate "
      "limit of 1e+50");
  check_bad_input(p + "'bodies=[{\"type\":\"strand\",\"root\":[0,0],\"mass\":1e-60}]'",
                  "bodies[0].mass: must be between 1e-50 and 1e+50");
}

TEST_CASE("limits: the sdf backend refuses numbers its arithmetic cannot carry") {
  const auto dir = test::temp_dir("limits-sdf");
  // an obstacle at 1e300 made the grid's area overflow and a lookup read a null candidate
  check_bad_input(
      "validate " + write_scene(dir, "far_obstacle.json", "sdf", kBall,
                                R"([{"id": "c", "shape": {"type": "circle", "center": [1e300, 0],
                                     "radius": 1}}])"),
      "far_obstacle.json: obstacles[0].shape.center[0]: 1e+300 is beyond the limit of 1e+09 in "
      "magnitude for obstacle and input numbers (backends/sdf/README.md, Limits)");
  check_bad_input("validate " + write_scene(dir, "far_ball.json", "sdf",
                                            R"({"x": [1e20, 0], "radius": 0.05})", kWall),
                  "particle 0 starts at (1e+20, 0), beyond the sdf backend's coordinate limit "
                  "of 1e+09");
  // a particle that would travel beyond the limit in one step stops the run (exit 1),
  // never "ok" with the particle frozen
  const std::string fast = write_scene(dir, "fast.json", "sdf",
                                       R"({"x": [0, 0], "v": [1e20, 0], "radius": 0.05})", kWall);
  const auto r = pinsim_cli("-q run " + fast + " --out " + (dir / "run").string());
  CHECK(r.code == 1);
  CHECK_THAT(r.output, Contains("particle 0 at t = 0 s: velocity (1e+20, 0) travels beyond the "
                                "sdf backend's limit of 1e+09 per step"));
  const auto s = nlohmann::json::parse(test::read_file(dir / "run" / "summary.json"));
  CHECK(s["status"] != "ok");
}

TEST_CASE("limits: box2d's preconditions are checked before Box2D is called") {
  const auto dir = test::temp_dir("limits-box2d");
  auto ball = [](const std::string& x, const std::string& r, const std::string& m = "1") {
    return R"({"x": )" + x + R"(, "v": [1, 0], "radius": )" + r + R"(, "mass": )" + m + "}";
  };
  // each of these aborted in b2Assert (exit 134), in validate too
  check_bad_input("validate " + write_scene(dir, "tiny.json", "box2d", ball("[0, 0]", "1e-300")),
                  "length scale 1e+300 (1 / the smallest particle radius 1e-300) is outside the "
                  "range the box2d backend can use, [1e-30, 1e+30]");
  check_bad_input("validate " + write_scene(dir, "huge.json", "box2d", ball("[0, 0]", "1e40")),
                  "length scale 1e-40 (1 / the smallest particle radius 1e+40) is outside");
  check_bad_input("validate " + write_scene(dir, "far.json", "box2d", ball("[1e39, 0]", "0.05")),
                  "particles[0]: position (2e+40, 0) Box2D units is beyond the limit of 1e+04 "
                  "(float rounding would exceed b2_linearSlop / 8) at length scale 20");
  check_bad_input(
      "validate " + write_scene(dir, "box.json", "box2d", ball("[0, 0]", "0.05"),
                                R"([{"id": "b", "shape": {"type": "box", "center": [1e5, 0],
                                     "half_size": [1, 1]}}])"),
      "box.json: obstacles[0].shape: unsupported by box2d (obstacle 'b'): a polygon piece: (");
  check_bad_input("validate " + (dir / "box.json").string(),
                  "Box2D units is beyond the limit of 1e+04 (float rounding would exceed "
                  "b2_linearSlop / 8) at length scale 20");
  check_bad_input(
      "validate " + write_scene(dir, "heavy.json", "box2d", ball("[0, 0]", "0.05", "1e40")),
      "particles[0]: mass 1e+40 is outside the range Box2D's float can use, [1e-30, 1e+30]");
  check_bad_input(
      "validate " + write_scene(dir, "sliver.json", "box2d", ball("[0, 0]", "0.05"),
                                R"([{"id": "s", "shape": {"type": "polygon",
                                     "points": [[1, 0], [2, 0], [3, 1e-10]]}}])"),
      "sliver.json: obstacles[0].shape: unsupported by box2d (obstacle 's'): a polygon piece: "
      "degenerate for Box2D");
}

TEST_CASE("limits: a truncated plugin file is named and skipped unless it is needed") {
  const auto dir = test::temp_dir("limits-plugin");
  const std::filesystem::path good = std::filesystem::path(PINSIM_BIN).parent_path().parent_path() /
                                     "plugins" / "libpinsim_plugin_gravity.so";
  REQUIRE(std::filesystem::exists(good));
  const std::string bytes = test::read_file(good);
  // cut inside the loadable segments: dlopen would map past the end (SIGBUS)
  test::write_file(dir / "libpinsim_plugin_cut.so", bytes.substr(0, bytes.size() / 3));
  test::write_file(dir / "libpinsim_plugin_stub.so", bytes.substr(0, 40));
  const std::string env = "PINSIM_PLUGIN_PATH=" + dir.string() + " ";
  auto r = test::shell(env + PINSIM_BIN " plugins 2>&1");
  CHECK(r.code == 0);
  CHECK_THAT(r.output, Contains("(broken)  " + (dir / "libpinsim_plugin_cut.so").string() +
                                ": not a pinsim plugin: truncated or corrupt (" +
                                std::to_string(bytes.size() / 3) + " bytes)"));
  CHECK_THAT(r.output, Contains("libpinsim_plugin_stub.so: not a pinsim plugin: not an ELF "
                                "shared library (40 bytes, shorter than an ELF header)"));
  CHECK_THAT(r.output, Contains("force   gravity "));
  for (const std::string& cmd : {std::string("plugins cut"), std::string("check-plugin cut")}) {
    CAPTURE(cmd);
    r = test::shell(env + PINSIM_BIN " " + cmd + " 2>&1");
    CHECK(r.code == 2);
    CHECK_THAT(r.output, Contains((dir / "libpinsim_plugin_cut.so").string() +
                                  ": not a pinsim plugin: truncated or corrupt"));
  }
  const std::string scene = write_scene(dir, "s.json", "none", kBall);
  r = test::shell(env + PINSIM_BIN " validate " + scene +
                  " --set 'forces=[{\"type\":\"cut\"}]' 2>&1");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("libpinsim_plugin_cut.so: not a pinsim plugin: truncated"));
  // a scene that does not name it is not concerned
  r = test::shell(env + PINSIM_BIN " validate " + scene + " 2>&1");
  CHECK(r.code == 0);
}

TEST_CASE("limits: a --view cairo cannot draw is refused before drawing") {
  const auto dir = test::temp_dir("limits-view");
  const std::string r =
      "render " + configs + "/projectile.json --out " + (dir / "p.png").string() + " --view ";
  check_bad_input(r + "0,0,1e-100,1e-100",
                  "--view 0,0,1e-100,1e-100: its larger side 1e-100 must be between 1e-3 and "
                  "1e3 times the picture's default size");
  check_bad_input(r + "-1e308,0,1e308,1", "--view -1e+308,0,1e+308,1: expected finite corners");
  check_bad_input(r + "100,100,101,101", "--view 100,100,101,101: does not overlap the scene");
  check_bad_input(r + "0,0,0.01,1",
                  "gives a picture 90000 pixels high at 900 wide, more than "
                  "the limit of 8192");
  const auto run = dir / "run";
  REQUIRE(pinsim_cli("-q run " + configs + "/projectile.json --out " + run.string()).code == 0);
  check_bad_input("replay " + run.string() + " --view 0,0,1e-100,1e-100",
                  "--view 0,0,1e-100,1e-100: its larger side");
  CHECK(pinsim_cli("-q render " + configs + "/projectile.json --out " + (dir / "ok.png").string() +
                   " --view 0,-1,2,1")
            .code == 0);
}

TEST_CASE("limits: check-plugin's --params and --param values are parsed within the limits") {
  // (deeper values once reached nlohmann's recursive copy and dump; 1000 levels here, as one
  // command-line argument may not exceed 128 KiB)
  const std::string deep = std::string(1000, '[') + std::string(1000, ']');
  for (const std::string opt : {"--params '", "--param 'k="}) {
    const auto r = pinsim_cli("check-plugin linear_spring " + opt + deep + "'");
    CAPTURE(opt);
    CHECK(r.code == 2);
    CHECK_THAT(r.output,
               Contains(opt == "--params '" ? "--params: [0][0][0]" : "--param k: [0][0]") &&
                   Contains("nested deeper than 256 levels of arrays and objects"));
  }
  // a value that is not JSON is still taken as text (and refused by the plugin's table)
  const auto r = pinsim_cli("check-plugin linear_spring --param k=stiff");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("stiff"));
}

TEST_CASE("limits: arrays, strings and particle counts have limits, raised from the environment") {
  const auto dir = test::temp_dir("limits-sizes");
  const std::string p = "validate " + configs + "/projectile.json --set ";
  // (a body may have 1e6 particles; one that size beside the projectile's ball is one too many)
  check_bad_input(p + "'bodies=[{\"type\":\"grid_blob\",\"nx\":1000,\"ny\":1000}]'",
                  "projectile.json: bodies[0]: 1000000 particles here make 1000001, "
                  "more than the limit of 1000000 particles in a scene ($PINSIM_MAX_PARTICLES "
                  "raises it)");
  std::string big = "[0";
  for (int i = 0; i < 1000000; ++i) big += ",0";
  test::write_file(dir / "long.json", "{\"description\": " + big + "]}");
  check_bad_input("validate " + (dir / "long.json").string(),
                  "long.json: description[999997]: more than 1000000 values and keys in the "
                  "document (the limit; $PINSIM_JSON_MAX_VALUES raises it)");
  auto r = test::shell("PINSIM_JSON_MAX_VALUES=2000000 " PINSIM_BIN " validate " +
                       (dir / "long.json").string() + " 2>&1");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("long.json: description[1000000]: an array of more than 1000000 "
                                "entries (the limit; $PINSIM_JSON_MAX_ARRAY raises it)"));
  test::write_file(dir / "string.json", "{\"name\": \"" + std::string((1u << 20) + 1, 'a') + "\"}");
  check_bad_input("validate " + (dir / "string.json").string(),
                  "string.json: name: a string of 1048577 bytes, longer than the limit of "
                  "1048576 ($PINSIM_JSON_MAX_STRING raises it)");
  // the environment raises (or lowers) them
  const std::string small = write_scene(dir, "small.json", "none", kBall);
  r = test::shell("PINSIM_JSON_MAX_ARRAY=1 " PINSIM_BIN " validate " + small + " 2>&1");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("small.json: particles[0].x[1]: an array of more than 1 entries"));
  r = test::shell("PINSIM_MAX_PARTICLES=0 " PINSIM_BIN " validate " + small + " 2>&1");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("$PINSIM_MAX_PARTICLES=0: expected a positive integer"));
  r = test::shell("PINSIM_JSON_MAX_VALUES=4 " PINSIM_BIN " validate " + small + " 2>&1");
  CHECK(r.code == 2);
  CHECK_THAT(r.output,
             Contains("small.json: time.dt: more than 4 values and keys in the document"));
  r = test::shell("PINSIM_JSON_MAX_VALUES=100 PINSIM_MAX_PARTICLES=2 " PINSIM_BIN " validate " +
                  small + " 2>&1");
  CHECK(r.code == 0);
}

TEST_CASE("a scene on a pipe is read once, also when the command looks at it twice") {
  // `run --backend NAME` reads the scene for its crosscheck params, then loads it: on a pipe
  // the second read got nothing ("unexpected end of input", exit 2). Both now parse the
  // text read once.
  const auto dir = test::temp_dir("scene-pipe");
  const auto r = test::shell("cat " PINSIM_SOURCE_DIR "/configs/pinball.json | " PINSIM_BIN
                             " -q run /dev/stdin --backend box2d --set time.duration=0.01 "
                             "--out " +
                             (dir / "run").string() + " 2>&1");
  INFO(r.output);
  CHECK(r.code == 0);
  const auto summary = nlohmann::json::parse(test::read_file(dir / "run" / "summary.json"));
  CHECK(summary["status"] == "ok");
  CHECK(summary["backend"] == "box2d");
  // `share` put the scene's text into the page by reading the file again: from a pipe the
  // page got an empty scene_text, with exit 0. A stand-in engine (the page only embeds its
  // text; its .plugins file lists what is built in) keeps this test free of the web build.
  test::write_file(dir / "engine.js", "/* stand-in engine */");
  test::write_file(dir / "engine.plugins", "sdf box2d none gravity linear_spring damped_spring\n");
  const auto s =
      test::shell("cat " PINSIM_SOURCE_DIR "/configs/pinball.json | PINSIM_WEB_MODULE=" +
                  (dir / "engine.js").string() + " " PINSIM_BIN " -q share /dev/stdin --out " +
                  (dir / "page.html").string() + " 2>&1");
  INFO(s.output);
  REQUIRE(s.code == 0);
  const std::string scene = test::read_file(PINSIM_SOURCE_DIR "/configs/pinball.json");
  const std::string page = test::read_file(dir / "page.html");
  // The page holds the scene text JSON-escaped: its first line is enough to find.
  const std::string first_line = scene.substr(0, scene.find('\n'));
  CHECK(page.find("\"scene_text\":\"" + first_line) != std::string::npos);
}

TEST_CASE(
    "limits: an input that never ends (a link to /dev/zero, a pipe) stops at the size limit") {
  // Reading the whole file before the 256 MiB check once took all memory on /dev/zero (a
  // device: no size to check before reading) or on `run <(yes)` (a pipe). The reads are now
  // bounded. A memory limit of 1 GiB makes the old behaviour fail here instead of swapping:
  // an address-space limit, or under ASan (whose shadow memory needs terabytes of address
  // space, so `ulimit -v` stops it at start) ASan's own resident-memory limit.
  const std::string memory_limit = test::kAddressSanitizer
                                       ? "ASAN_OPTIONS=$ASAN_OPTIONS:hard_rss_limit_mb=1024 "
                                       : "ulimit -v 1048576; ";
  const auto dir = test::temp_dir("limits-endless");
  std::filesystem::create_symlink("/dev/zero", dir / "zero.json");
  const std::string zero = (dir / "zero.json").string();
  const std::string limit =
      "larger than the limit of " + std::to_string(256u << 20) + " bytes for a JSON file";
  for (const std::string& cmd :
       {"validate " + zero, "run " + zero + " --out " + (dir / "run").string(),
        "run " + zero + " --backend box2d --out " + (dir / "run").string(),
        "play --rerun " + zero}) {
    const auto r = test::shell(memory_limit + PINSIM_BIN " " + cmd + " 2>&1");
    CAPTURE(cmd);
    CHECK(r.code == 2);
    CHECK_THAT(r.output, Contains(zero + ": " + limit));
  }
  // A pipe that never ends, as `run <(yes)` gives.
  const auto r = test::shell("yes | (" + memory_limit + PINSIM_BIN " validate /dev/stdin) 2>&1");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("/dev/stdin: " + limit));
}
