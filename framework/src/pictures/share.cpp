#include "pictures/share.hpp"

#include <stdexcept>

#include "core/html_text.hpp"

namespace pinsim {
namespace {
void replace_once(std::string& s, const std::string& key, const std::string& value) {
  const auto at = s.find(key);
  if (at == std::string::npos) throw std::logic_error("share template lacks " + key);
  s.replace(at, key.size(), value);
}
}  // namespace

std::string share_html(const SharePage& page) {
  if (page.engine_js.find("</script") != std::string::npos)
    throw std::runtime_error("the web engine contains \"</script\" and cannot be inlined");
  std::string data = page.data.dump();
  for (std::size_t at = 0; (at = data.find("</", at)) != std::string::npos; at += 3)
    data.replace(at, 2, "<\\/");
  std::string html = kShareTemplate;
  replace_once(html, "@PINSIM_TITLE@", html_text(page.title));
  replace_once(html, "@PINSIM_PAGE_DATA@", data);
  replace_once(html, "/*@PINSIM_ENGINE@*/", page.engine_js);
  return html;
}

}  // namespace pinsim
