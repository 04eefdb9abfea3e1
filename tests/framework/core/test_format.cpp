// core/format.hpp: the text CSV cells, reports and messages depend on.
#include <catch2/catch.hpp>
#include <limits>

#include "core/format.hpp"

using pinsim::num;

TEST_CASE("num: printf %g text, 6 significant digits by default") {
  CHECK(num(0.001) == "0.001");
  CHECK(num(2.5) == "2.5");
  CHECK(num(100.0) == "100");
  CHECK(num(1e6) == "1e+06");
  CHECK(num(1.0 / 3.0) == "0.333333");
  CHECK(num(-1e-5) == "-1e-05");
}

TEST_CASE("num: fewer digits for short report values") {
  CHECK(num(1.0 / 3.0, 3) == "0.333");
  CHECK(num(12345.0, 3) == "1.23e+04");
}

TEST_CASE("num: names for the non-finite values") {
  CHECK(num(std::numeric_limits<double>::quiet_NaN()) == "nan");
  CHECK(num(-std::numeric_limits<double>::quiet_NaN()) == "nan");
  CHECK(num(std::numeric_limits<double>::infinity()) == "inf");
  CHECK(num(-std::numeric_limits<double>::infinity()) == "-inf");
}
