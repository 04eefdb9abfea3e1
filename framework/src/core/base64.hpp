// Bytes as base64 text (RFC 4648, with '=' padding): for data: URIs in pages and results.
#pragma once

#include <string>
#include <string_view>

namespace pinsim {

/// `bytes` in base64.
std::string base64(std::string_view bytes);

}  // namespace pinsim
