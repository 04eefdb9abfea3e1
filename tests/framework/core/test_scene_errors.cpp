// Every kind of bad scene gets one error naming the file, the JSON path and what was
// expected, before anything runs.
#include <catch2/catch.hpp>

#include "core/json_read.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "test_support.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;

namespace {

const char* kGood = R"({
  "time": {"dt": 0.01, "duration": 1.0},
  "particles": [{"x": [0, 0], "v": [1, 0], "mass": 1.0, "radius": 0.1}],
  "forces": [{"type": "gravity", "params": {"g": [0, -9.81]}}]
})";

// Parses kGood with one override, then builds the simulation.
void build(const std::vector<std::string>& set, const std::string& text = kGood) {
  const Scene s = parse_scene(text, "bad.json", ".", set);
  PluginLoader loader(plugin_search_dirs());
  Simulation sim(s, loader);
}

}  // namespace

TEST_CASE("scene errors: the good scene builds") { REQUIRE_NOTHROW(build({})); }

TEST_CASE("scene errors: malformed JSON names file, line and column") {
  REQUIRE_THROWS_WITH(build({}, "{\n  \"time\": {\"dt\": 0.01,, }\n}"),
                      Contains("bad.json:2:") && Contains("malformed JSON"));
}

TEST_CASE("scene errors: comments are allowed") {
  REQUIRE_NOTHROW(build({}, std::string("// a comment\n/* block */\n") + kGood));
}

TEST_CASE("scene errors: unknown force plugin") {
  REQUIRE_THROWS_WITH(build({"forces[0].type=antigravity"}),
                      Contains("bad.json: forces[0]") && Contains("unknown plugin 'antigravity'"));
}

TEST_CASE("scene errors: unknown backend") {
  REQUIRE_THROWS_WITH(build({"backend=warpdrive"}),
                      Contains("bad.json: backend") && Contains("unknown plugin 'warpdrive'"));
}

TEST_CASE("scene errors: a force used as a backend") {
  REQUIRE_THROWS_WITH(build({"backend=gravity"}), Contains("is a force, not a backend"));
}

TEST_CASE("scene errors: unknown parameter names the key and the known ones") {
  REQUIRE_THROWS_WITH(build({"forces[0].params.gee=1"}),
                      Contains("bad.json: forces[0].params.gee: unknown parameter of plugin "
                               "'gravity'") &&
                          Contains("known:") && Contains("g"));
}

TEST_CASE("scene errors: wrong parameter type") {
  REQUIRE_THROWS_WITH(build({"forces[0].params.g=\"down\""}),
                      Contains("bad.json: forces[0].params.g: expected [x, y]"));
}

TEST_CASE("scene errors: unknown top-level and nested keys") {
  REQUIRE_THROWS_WITH(build({"tiem={}"}), Contains("bad.json: tiem: unknown key"));
  REQUIRE_THROWS_WITH(build({"time.dtt=0.1"}), Contains("bad.json: time.dtt: unknown key"));
  REQUIRE_THROWS_WITH(build({"particles[0].velocity=[1,2]"}),
                      Contains("bad.json: particles[0].velocity: unknown key"));
}

TEST_CASE("scene errors: dt must be > 0") {
  REQUIRE_THROWS_WITH(build({"time.dt=0"}), Contains("bad.json: time.dt: must be > 0, got 0"));
  REQUIRE_THROWS_WITH(build({"time.dt=-0.1"}), Contains("bad.json: time.dt: must be > 0"));
  REQUIRE_THROWS_WITH(build({"time.dt=\"fast\""}),
                      Contains("bad.json: time.dt: expected a number, got string"));
}

TEST_CASE("scene errors: duration must be >= 0") {
  REQUIRE_THROWS_WITH(build({"time.duration=-1"}),
                      Contains("bad.json: time.duration: must be >= 0, got -1"));
  REQUIRE_NOTHROW(build({"time.duration=0"}));
}

TEST_CASE("scene errors: mass must be > 0") {
  REQUIRE_THROWS_WITH(build({"particles[0].mass=0"}),
                      Contains("bad.json: particles[0].mass: must be > 0, got 0"));
  REQUIRE_THROWS_WITH(build({"particles[0].mass=-2"}),
                      Contains("bad.json: particles[0].mass: must be > 0, got -2"));
}

TEST_CASE("scene errors: negative radius") {
  REQUIRE_THROWS_WITH(build({"particles[0].radius=-0.1"}),
                      Contains("bad.json: particles[0].radius: must be >= 0"));
}

TEST_CASE("scene errors: missing time and missing particles") {
  REQUIRE_THROWS_WITH(build({}, R"({"particles": [{"x": [0, 0]}]})"),
                      Contains("bad.json: time: required"));
  REQUIRE_THROWS_WITH(build({}, R"({"time": {"dt": 0.1, "duration": 1}})"),
                      Contains("bad.json: (top level): the scene has no particles"));
}

TEST_CASE("scene errors: element indices out of range") {
  REQUIRE_THROWS_WITH(build({"forces[0].elements=[0, 3]"}),
                      Contains("bad.json: forces[0].elements[1]: particle index must be an "
                               "integer in [0, 1)"));
}

TEST_CASE("scene errors: missing scene file") {
  REQUIRE_THROWS_WITH(load_scene("/nonexistent/scene.json"),
                      Contains("/nonexistent/scene.json: scene file not found"));
}

TEST_CASE("scene errors: --set with a bad path or form") {
  REQUIRE_THROWS_WITH(build({"time.dt"}), Contains("expected PATH=VALUE"));
  REQUIRE_THROWS_WITH(build({"particles[5].mass=1"}), Contains("no index '5'"));
  REQUIRE_THROWS_WITH(build({"time.dt.x=1"}), Contains("time.dt is a number"));
}

TEST_CASE("scene errors: --set overrides values") {
  const Scene s =
      parse_scene(kGood, "good.json", ".", {"time.dt=0.0005", "forces[0].params.g=[0,-1]"});
  CHECK(s.dt == 0.0005);
  CHECK(s.steps() == 2000);
  CHECK(s.forces[0].params["g"][1] == -1);
}

TEST_CASE("scene: whole-body elements from a body's set or an explicit list of lists") {
  const char* text = R"({
    "time": {"dt": 0.01, "duration": 1.0},
    "bodies": [{"type": "ring_blob", "name": "blob", "center": [0, 0], "count": 6}],
    "forces": [{"type": "area_pressure", "elements": {"body": "blob", "set": "boundary"}}]
  })";
  const Scene s = parse_scene(text, "whole.json", ".");
  CHECK(s.resolve_elements(s.forces[0], 0) == std::vector<uint32_t>{6, 0, 1, 2, 3, 4, 5});
  PluginLoader loader(plugin_search_dirs());
  REQUIRE_NOTHROW(Simulation(s, loader));
  // Explicit lists: each element is a list of any length, stored length first.
  const Scene e =
      parse_scene(text, "whole.json", ".", {"forces[0].elements=[[0, 1, 2], [2, 3, 4, 5]]"});
  CHECK(e.resolve_elements(e.forces[0], 0) == std::vector<uint32_t>{3, 0, 1, 2, 4, 2, 3, 4, 5});
}

TEST_CASE("scene errors: whole-body forces name the set and what they need") {
  const char* text = R"({
    "time": {"dt": 0.01, "duration": 1.0},
    "bodies": [{"type": "ring_blob", "name": "blob", "center": [0, 0], "count": 6}],
    "forces": [{"type": "area_pressure", "elements": {"body": "blob", "set": "boundary"}}]
  })";
  REQUIRE_THROWS_WITH(build({"forces[0].elements.set=edges"}, text),
                      Contains("bad.json: forces[0].elements.set: set 'edges' of body 'blob' has "
                               "elements of 2 particles, but plugin 'area_pressure' needs whole "
                               "bodies (elements of any length)"));
  REQUIRE_THROWS_WITH(build({"forces[0].type=linear_spring"}, text),
                      Contains("has whole bodies (elements of any length), but plugin "
                               "'linear_spring' needs elements of 2 particles"));
  REQUIRE_THROWS_WITH(build({"forces[0].elements=[[0, 1, 2], []]"}, text),
                      Contains("forces[0].elements[1]: expected a list of particle indices"));
  REQUIRE_THROWS_WITH(build({"forces[0].elements=[[0, 1]]"}, text),
                      Contains("bad.json: forces[0]: element 0 has 2 particle(s)"));
}

TEST_CASE("scene errors: nesting deeper than the limit is refused while parsing") {
  // 100,000 levels used to overflow the stack in recursive copies and dumps (SIGSEGV).
  for (const std::size_t depth : {257u, 100000u}) {
    CAPTURE(depth);
    const std::string deep = std::string(depth, '[') + std::string(depth, ']');
    const std::string text =
        R"({"time": {"dt": 0.01, "duration": 1}, "particles": [], "x": )" + deep + "}";
    REQUIRE_THROWS_WITH(build({}, text),
                        Contains("bad.json: x") && Contains("nested deeper than 256 levels"));
  }
  // 256 levels are fine as JSON (and then refused for the unknown key, not the depth).
  const std::string ok = std::string(255, '[') + std::string(255, ']');
  REQUIRE_THROWS_WITH(build({}, R"({"time": {"dt": 0.01, "duration": 1},
                                  "particles": [{"x": [0, 0]}], "x": )" +
                                    ok + "}"),
                      Contains("bad.json: x: unknown key"));
  // Through --set too.
  REQUIRE_THROWS_WITH(build({"x=" + std::string(300, '[') + std::string(300, ']')}),
                      Contains("nested deeper than 256 levels"));
}

TEST_CASE("scene errors: a duplicate key is refused, naming its path") {
  REQUIRE_THROWS_WITH(build({}, R"({"time": {"dt": 0.01, "dt": 0.02, "duration": 1}})"),
                      Contains("bad.json: time.dt: duplicate key \"dt\""));
  REQUIRE_THROWS_WITH(build({}, R"({"time": {"dt": 0.01, "duration": 1},
                   "particles": [{"x": [0, 0]}, {"x": [1, 0], "mass": 1, "mass": 2}]})"),
                      Contains("bad.json: particles[1].mass: duplicate key \"mass\""));
}

TEST_CASE("scene errors: a number beyond a double's range names file, line, column and path") {
  REQUIRE_THROWS_WITH(build({}, "{\"time\": {\"dt\": 0.01,\n  \"duration\": 1e400}}"),
                      Contains("bad.json:2:15: time.duration: number 1e400 is out of range"));
  // In an array: the entry being read, not the one before it.
  REQUIRE_THROWS_WITH(build({}, R"({"time": {"dt": 0.01, "duration": 1},
    "particles": [{"x": [0, 0]}, {"x": [1, -1e999]}]})"),
                      Contains("bad.json:2:44: particles[1].x[1]: number -1e999 is out of range"));
  REQUIRE_THROWS_WITH(build({}, "[1e999]"), Contains("bad.json:1:2: [0]: number 1e999"));
  REQUIRE_THROWS_WITH(build({"time.dt=1e999"}),
                      Contains("--set time.dt=") && Contains("number 1e999 is out of range"));
}

TEST_CASE("scene errors: --set with an index too large for any array") {
  REQUIRE_THROWS_WITH(build({"particles[99999999999999999999].x=1"}),
                      Contains("particles has 1 entries, no index '99999999999999999999'"));
}

TEST_CASE("input errors: a scene's errors are SceneError, other files' InputError") {
  // One base for every bad input (main maps it to exit 2); SceneError for scene files.
  const Loc scene{"s.json", "", true}, rubric{"r.json", ""};
  try {
    (scene / "time")[0].fail("expected a number");
    FAIL("no throw");
  } catch (const SceneError& e) {
    CHECK(std::string(e.what()) == "s.json: time[0]: expected a number");
  }
  try {
    (rubric / "tests")[2].fail("expected a test");
    FAIL("no throw");
  } catch (const SceneError&) {
    FAIL("a rubric's error is not a SceneError");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()) == "r.json: tests[2]: expected a test");
  }
  REQUIRE_THROWS_AS(build({}, "{\"time\": 1}"), SceneError);
  REQUIRE_THROWS_AS(build({"time.dt"}), InputError);  // a malformed --set
}

TEST_CASE("scene errors: a grid blob of more particles than a body may have") {
  // 1e6 x 1e6 would be 1e12 particles (and wrap a 32-bit count): refused before any is made
  REQUIRE_THROWS_WITH(build({"bodies=[{\"type\": \"grid_blob\", \"nx\": 1000000, \"ny\": 2}]"}),
                      Contains("bad.json: bodies[0].ny: nx * ny = 2000000 particles, more than "
                               "the 1000000 a body may have"));
}

TEST_CASE("scene errors: --set cannot nest deeper than the parser's limit") {
  // 60000 keys once overflowed the stack in the recursive copy of the document
  std::string path = "contacts";
  for (int i = 0; i < 60000; ++i) path += ".a";
  REQUIRE_THROWS_WITH(build({path + "=1"}),
                      Contains("bad.json: --set contacts.a.a.") &&
                          Contains("...: nests 60001 levels deep, more than the limit of 256"));
  REQUIRE_THROWS_WITH(build({"contacts.a=" + std::string(255, '[') + std::string(255, ']')}),
                      Contains("nests 257 levels deep, more than the limit of 256"));
}

TEST_CASE("scene errors: a --set value that is not UTF-8 is refused, naming the path") {
  REQUIRE_THROWS_WITH(build({"name=ab\xff\xfe"}),
                      Contains("bad.json: --set name: the value is not valid UTF-8"));
}
