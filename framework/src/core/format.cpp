#include "core/format.hpp"

#include <cmath>
#include <cstdio>

namespace pinsim {

std::string num(double x, int digits) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, x);
  return buf;
}

}  // namespace pinsim
