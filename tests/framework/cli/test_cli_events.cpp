// `output.events` through the command line: a bad value is exit 2 naming file and path.
#include <catch2/catch.hpp>

#include "test_support.hpp"

using Catch::Matchers::Contains;
using pinsim::test::pinsim_cli;

TEST_CASE("cli: output.events other than impacts, all or none is exit 2 naming the path") {
  const std::string scene = PINSIM_SOURCE_DIR "/configs/projectile.json";
  const auto r = pinsim_cli("run " + scene + " --set output.events=some");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("[error]") && Contains("projectile.json") &&
                           Contains("output.events") &&
                           Contains("expected \"impacts\", \"all\" or \"none\", got \"some\""));
  const auto n = pinsim_cli("run " + scene + " --set output.events=42");
  CHECK(n.code == 2);
  CHECK_THAT(n.output, Contains("output.events") && Contains("expected a string"));
}
