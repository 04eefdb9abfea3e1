// Reading a JSON input whole when it may have no size to check first (a pipe, a device).
#pragma once

#include <istream>
#include <string>

#include "core/json_read.hpp"

namespace pinsim {

/// All of `in` as text, reading no more than max_bytes + 1 bytes: InputError "<label>: larger
/// than the limit of N bytes for a JSON file" past it. For files that may be a pipe or a
/// device (`run <(cmd)`, a link to /dev/zero), which no size check before reading can bound.
std::string read_json_text(std::istream& in, const std::string& label,
                           std::size_t max_bytes = JsonLimits{}.max_bytes);

}  // namespace pinsim
