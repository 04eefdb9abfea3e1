// The page of `pinsim share`: share_template.html with the engine, the scene and the table
// picture filled in.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace pinsim {

extern const char* const kShareTemplate;

struct SharePage {
  std::string title;      ///< the scene's name
  std::string engine_js;  ///< pinsim_web.js (the wasm embedded in it)
  nlohmann::json data;    ///< scene_text, scene_file, background, view, width, height, scale
};

/// The page's HTML. Text that could end a <script> element early ("</") is escaped in the
/// embedded JSON and refused in the engine.
std::string share_html(const SharePage& page);

}  // namespace pinsim
