// `pinsim run --threads N`: the state hash and the trajectory bytes do not depend on N.
//
// Why they must be equal (docs/threads.md): the host limits oneTBB to N threads; the only
// loops that use them split their work in chunks fixed by the item count
// (pinsim/parallel.hpp). The sdf backend marches each particle with its own inputs (pair
// contacts are scheduled serially first) and adds counters and events per chunk, in chunk
// order; the SDK's ConstraintSpring computes each element's terms apart and subtracts them
// per particle in element order, the order of the serial loop. No floating-point sum is
// regrouped, so every double is computed by the same operations for any N.
#include <catch2/catch.hpp>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "test_support.hpp"

using nlohmann::json;

namespace {

const std::string configs = PINSIM_SOURCE_DIR "/configs";

/// 30 x 30 = 900 balls (above the sdf backend's parallel threshold of 256) falling onto a
/// floor and two round bumpers, with or without ball-ball contacts.
json many_balls(bool contacts) {
  json s = {{"name", "many_balls"},
            {"time", {{"dt", 0.001}, {"duration", 0.6}}},
            {"integrator", "symplectic_euler"},
            {"backend", {{"name", "sdf"}}},
            {"bodies",
             {{{"type", "grid_blob"},
               {"name", "balls"},
               {"origin", {-0.6, 0.2}},
               {"nx", 30},
               {"ny", 30},
               {"spacing", 0.04},
               {"mass", 0.01},
               {"radius", 0.012},
               {"velocity", {0.3, -1.0}}}}},
            {"forces", {{{"type", "gravity"}, {"params", {{"g", {0.0, -9.81}}}}}}},
            {"obstacles",
             {{{"id", "floor"},
               {"shape", {{"type", "box"}, {"center", {0.0, -0.5}}, {"half_size", {2.0, 0.5}}}},
               {"material", {{"restitution", 0.5}, {"friction", 0.1}}}},
              {{"id", "bumper"},
               {"shape", {{"type", "circle"}, {"center", {0.0, 0.1}}, {"radius", 0.15}}},
               {"material", {{"restitution", 0.9}}}}}},
            {"output", {{"every", 20}}}};
  if (contacts) s["contacts"] = {{"particles", true}, {"restitution", 0.5}};
  return s;
}

/// A 70 x 70 grid of damped springs (9660 edges + 9522 shear springs, above ConstraintSpring's
/// parallel threshold of 8192) dropping onto a floor.
json spring_grid() {
  return {{"name", "spring_grid"},
          {"time", {{"dt", 0.0005}, {"duration", 0.1}}},
          {"integrator", "symplectic_euler"},
          {"backend", {{"name", "sdf"}}},
          {"bodies",
           {{{"type", "grid_blob"},
             {"name", "sheet"},
             {"origin", {-0.35, 0.05}},
             {"nx", 70},
             {"ny", 70},
             {"spacing", 0.01},
             {"mass", 0.001},
             {"radius", 0.003},
             {"velocity", {0.2, -2.0}}}}},
          {"forces",
           {{{"type", "gravity"}, {"params", {{"g", {0.0, -9.81}}}}},
            {{"type", "damped_spring"},
             {"params", {{"ks", 50.0}, {"kd", 0.01}}},
             {"elements", {{"body", "sheet"}, {"set", "edges"}}}},
            {{"type", "damped_spring"},
             {"params", {{"ks", 20.0}, {"kd", 0.01}}},
             {"elements", {{"body", "sheet"}, {"set", "shear"}}}}}},
          {"obstacles",
           {{{"id", "floor"},
             {"shape", {{"type", "box"}, {"center", {0.0, -0.5}}, {"half_size", {2.0, 0.5}}}},
             {"material", {{"restitution", 0.3}}}}}},
          {"output", {{"every", 10}}}};
}

struct Run {
  json summary;
  std::string trajectory, events;
};

Run run(const std::string& scene, unsigned threads, const std::string& extra = "") {
  const auto dir = pinsim::test::temp_dir("threads");
  const auto r =
      pinsim::test::pinsim_cli("-q run " + scene + " --threads " + std::to_string(threads) + " " +
                               extra + " --out " + dir.string() + " --overwrite");
  INFO(r.output);
  REQUIRE(r.code == 0);
  Run out{json::parse(pinsim::test::read_file(dir / "summary.json")),
          pinsim::test::read_file(dir / "trajectory.csv"), ""};
  if (std::filesystem::exists(dir / "events.csv"))
    out.events = pinsim::test::read_file(dir / "events.csv");
  CHECK(out.summary["threads"] == threads);
  CHECK(out.summary["status"] == "ok");
  return out;
}

std::string write_scene(const json& s, const std::string& name) {
  const auto path = pinsim::test::temp_dir("threads-scene") / (name + ".json");
  std::ofstream(path) << s.dump(1);
  return path.string();
}

/// Runs the scene with 1, 2 and 3 threads and requires the same bits.
void same_for_1_2_3(const std::string& scene, const std::string& extra = "") {
  const Run one = run(scene, 1, extra);
  for (unsigned n : {2u, 3u}) {
    INFO(scene << " --threads " << n);
    const Run other = run(scene, n, extra);
    CHECK(other.summary["state_hash"] == one.summary["state_hash"]);
    CHECK(other.summary["contacts"] == one.summary["contacts"]);
    CHECK(other.trajectory == one.trajectory);
    CHECK(other.events == one.events);
  }
}

}  // namespace

TEST_CASE("threads: the pinball table gives the same bits with 1, 2 and 3 threads") {
  same_for_1_2_3(configs + "/pinball.json");
}

TEST_CASE("threads: 900 balls without ball contacts, 1, 2 and 3 threads alike") {
  const std::string scene = write_scene(many_balls(false), "balls");
  same_for_1_2_3(scene);
  // the scene does hit obstacles: the test is not about balls flying freely
  CHECK(run(scene, 2).summary["contacts"].get<uint64_t>() > 100);
}

TEST_CASE("threads: 900 balls with ball contacts, 1, 2 and 3 threads alike") {
  const std::string scene = write_scene(many_balls(true), "balls_contacts");
  same_for_1_2_3(scene);
}

TEST_CASE("threads: a grid of 19182 damped springs, 1, 2 and 3 threads alike") {
  const std::string scene = write_scene(spring_grid(), "springs");
  same_for_1_2_3(scene);
  same_for_1_2_3(scene, "--integrator implicit_euler --set time.duration=0.01");
}

TEST_CASE("threads: the Box2D backend runs with threads (serially inside), same bits") {
  same_for_1_2_3(configs + "/pinball.json", "--backend box2d --set time.duration=1");
}

TEST_CASE("threads: --threads outside 1..256 is refused with exit 2") {
  for (const char* bad : {"0", "257", "-1", "two"}) {
    INFO(bad);
    const auto r = pinsim::test::pinsim_cli("-q run " + configs + "/projectile.json --threads " +
                                            std::string(bad));
    CHECK(r.code == 2);
    CHECK_THAT(r.output, Catch::Matchers::Contains("--threads"));
  }
}
