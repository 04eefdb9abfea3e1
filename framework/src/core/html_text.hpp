// Text for an HTML element's content: the share page's title, the grader's html output.
#pragma once

#include <string>
#include <string_view>

namespace pinsim {

/// `text` with &, < and > escaped (quotes only matter in attributes).
inline std::string html_text(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    if (c == '&')
      out += "&amp;";
    else if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else
      out += c;
  }
  return out;
}

}  // namespace pinsim
