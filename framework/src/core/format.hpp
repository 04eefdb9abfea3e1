// Numbers as text: the one formatter for CSV cells, reports and error messages.
#pragma once

#include <string>

namespace pinsim {

/// `x` as printf's "%.<digits>g" ("0.001", "1e+06", "2.5"; 6 digits by default, 3 for
/// short report values); "nan", "inf" and "-inf" for those. CSV cells depend on this text.
std::string num(double x, int digits = 6);

}  // namespace pinsim
