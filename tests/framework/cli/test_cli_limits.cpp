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
