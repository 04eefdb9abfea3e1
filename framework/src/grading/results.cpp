#include "grading/results.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <sstream>
#include <stdexcept>

#include "core/format.hpp"
#include "core/html_text.hpp"
#include "grading/sandbox.hpp"
#include "grading/text.hpp"

namespace fs = std::filesystem;

namespace pinsim::grading {
namespace {

std::string xml_escape(const std::string& raw) {
  const std::string s = sanitize_text(raw);
  std::string o;
  for (char c : s) {
    switch (c) {
      case '<':
        o += "&lt;";
        break;
      case '>':
        o += "&gt;";
        break;
      case '&':
        o += "&amp;";
        break;
      case '"':
        o += "&quot;";
        break;
      case '\'':
        o += "&apos;";
        break;
      default:
        o += c;
    }
  }
  return o;
}

/// Text for HTML: sanitized, then escaped.
std::string html_escape(const std::string& raw) { return html_text(sanitize_text(raw)); }

/// A block of preformatted text (empty for none), without the newlines it starts and ends
/// with.
std::string pre(const std::string& text) {
  const std::size_t a = text.find_first_not_of('\n');
  if (a == std::string::npos) return "";
  const std::size_t b = text.find_last_not_of('\n');
  return "<pre>" + html_escape(text.substr(a, b + 1 - a)) + "</pre>\n";
}

std::string str(const nlohmann::json& j, const char* key) {
  return j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : std::string();
}

double number(const nlohmann::json& j, const char* key) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : 0.0;
}

}  // namespace

void write_atomically(const fs::path& file, const std::string& text) {
  const fs::path tmp = file.string() + ".tmp." + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0)
    throw std::runtime_error("cannot write " + tmp.string() + ": " + std::strerror(errno));
  const char* p = text.data();
  std::size_t left = text.size();
  bool ok = true;
  while (ok && left > 0) {
    const ssize_t w = ::write(fd, p, left);
    if (w < 0 && errno == EINTR) continue;
    ok = w > 0;
    if (ok) {
      p += w;
      left -= static_cast<std::size_t>(w);
    }
  }
  const int saved = errno;
  ok = ok && ::fsync(fd) == 0;
  ok = ::close(fd) == 0 && ok;
  if (!ok || ::rename(tmp.c_str(), file.c_str()) != 0) {
    const std::string why = std::strerror(ok ? errno : saved);
    ::unlink(tmp.c_str());
    throw std::runtime_error("cannot write " + file.string() + ": " + why);
  }
}

std::string junit_xml(const nlohmann::json& results, const std::string& suite) {
  std::ostringstream x;
  int failures = 0;
  for (const auto& t : results["tests"]) failures += str(t, "status") != "passed";
  x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuite name=\"" << xml_escape(suite)
    << "\" tests=\"" << results["tests"].size() << "\" failures=\"" << failures << "\" time=\""
    << num(number(results, "execution_time")) << "\">\n";
  for (const auto& t : results["tests"]) {
    x << "  <testcase name=\"" << xml_escape(str(t, "name")) << "\" time=\""
      << num(number(t, "execution_time")) << "\"";
    if (str(t, "status") == "passed") {
      x << "/>\n";
    } else {
      x << ">\n    <failure message=\"" << xml_escape(str(t, "name")) << "\">"
        << xml_escape(str(t, "output")) << "</failure>\n  </testcase>\n";
    }
  }
  x << "</testsuite>\n";
  return x.str();
}

std::string summary_text(const nlohmann::json& results, const std::string& rubric_name,
                         bool with_outputs) {
  std::ostringstream s;
  int passed = 0;
  for (const auto& t : results["tests"]) passed += str(t, "status") == "passed";
  s << sanitize_text(rubric_name) << ": " << num(number(results, "score")) << " / "
    << num(number(results, "max_score")) << " points, " << passed << " of "
    << results["tests"].size() << " tests passed\n";
  // The top-level output when it says more than this summary does (why grading was refused
  // or did not finish): the summary file and the terminal show it too.
  if (with_outputs) {
    const std::string top = str(results, "output");
    if (!top.empty() && top != summary_text(results, rubric_name, false))
      s << sanitize_text(top) << (top.back() == '\n' ? "" : "\n");
  }
  for (const auto& t : results["tests"]) {
    s << "  [" << (str(t, "status") == "passed" ? "pass" : "FAIL") << "] " << str(t, "number")
      << ". " << sanitize_text(str(t, "name")) << " (" << num(number(t, "score")) << "/"
      << num(number(t, "max_score")) << ")\n";
    if (with_outputs && str(t, "status") != "passed") {
      std::istringstream lines(sanitize_text(str(t, "output")));
      for (std::string l; std::getline(lines, l);) s << "        " << l << "\n";
    }
  }
  return s.str();
}

nlohmann::json gradescope_results(const nlohmann::json& results) {
  nlohmann::json r = results;
  if (!r.contains("tests") || !r["tests"].is_array()) return r;
  for (auto& t : r["tests"]) {
    if (!t.is_object() || !t.contains("picture")) continue;
    const nlohmann::json p = t["picture"];
    t.erase("picture");
    const std::string text = str(t, "output");
    const std::size_t at = std::min<std::size_t>(p.value("at", text.size()), text.size());
    // The PNG's base64 text is [A-Za-z0-9+/=] only: nothing in it needs escaping.
    const std::string png = p.value("png_base64", "");
    if (png.find_first_not_of(
            "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/=") !=
        std::string::npos)
      continue;
    t["output"] = pre(text.substr(0, at)) + "<p><img src=\"data:image/png;base64," + png +
                  "\" width=\"" + std::to_string(p.value("width", 0)) + "\" height=\"" +
                  std::to_string(p.value("height", 0)) +
                  "\" alt=\"your path and the reference's on the table\"></p>\n<p>" +
                  html_escape(p.value("caption", "")) + "</p>\n" + pre(text.substr(at));
    t["output_format"] = "html";
  }
  return r;
}

void write_results(const fs::path& dir, const nlohmann::json& results, const std::string& name) {
  // error_handler::replace: a string that is somehow still not UTF-8 cannot stop the dump.
  write_atomically(
      dir / "results.json",
      gradescope_results(results).dump(2, ' ', false, nlohmann::json::error_handler_t::replace) +
          "\n");
  write_atomically(dir / "junit.xml", junit_xml(results, name));
  write_atomically(dir / "summary.txt", summary_text(results, name));
}

nlohmann::json failed_results(const std::string& reason, double max_score) {
  return {{"score", 0.0},
          {"max_score", max_score},
          {"execution_time", 0.0},
          {"output", sanitize_text(reason)},
          {"visibility", "visible"},
          {"tests", nlohmann::json::array()},
          {"extra_data", sandbox_extra_data()}};
}

nlohmann::json sandbox_extra_data() {
  return {{"sandbox",
           {{"mode", sandbox_mode_name(sandbox_mode())},
            {"detail", sanitize_text(sandbox_description())}}}};
}

}  // namespace pinsim::grading
