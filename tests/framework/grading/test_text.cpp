// The grader's text sanitizer and bounded capture: whatever bytes a submission prints, the
// result is valid UTF-8 without control characters, and memory stays bounded.
#include <catch2/catch.hpp>
#include <string>

#include "grading/text.hpp"

using pinsim::grading::BoundedText;
using pinsim::grading::sanitize_text;

namespace {

/// Strict UTF-8 check (RFC 3629), independent of the code under test.
bool valid_utf8(const std::string& s) {
  for (std::size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    std::size_t n = c < 0x80 ? 1 : (c >> 5) == 6 ? 2 : (c >> 4) == 14 ? 3 : (c >> 3) == 30 ? 4 : 0;
    if (n == 0 || i + n > s.size()) return false;
    for (std::size_t k = 1; k < n; ++k)
      if ((static_cast<unsigned char>(s[i + k]) & 0xC0) != 0x80) return false;
    i += n;
  }
  return true;
}

bool has_control(const std::string& s) {
  for (char c : s)
    if ((static_cast<unsigned char>(c) < 0x20 && c != '\n' && c != '\t') || c == 0x7F) return true;
  return false;
}

}  // namespace

TEST_CASE("sanitize_text: a multi-byte character cut at any byte becomes U+FFFD") {
  const std::string euro = "\xE2\x82\xAC";  // U+20AC, three bytes
  const std::string text = "ab" + euro + euro + "cd";
  for (std::size_t cut = 0; cut <= text.size(); ++cut) {
    CAPTURE(cut);
    const std::string head = sanitize_text(text.substr(0, cut));
    const std::string tail = sanitize_text(text.substr(cut));
    CHECK(valid_utf8(head));
    CHECK(valid_utf8(tail));
    // A cut inside a character leaves its bytes as replacement characters, never dropped
    // silently: every part that was whole comes through unchanged.
    if (cut == 2 || cut == 5 || cut == 8) CHECK(head + tail == text);
  }
  CHECK(sanitize_text("ab\xE2\x82") == "ab\xEF\xBF\xBD\xEF\xBF\xBD");
}

TEST_CASE("sanitize_text: invalid forms and control characters") {
  CHECK(sanitize_text("\xC0\xAF") == "\xEF\xBF\xBD\xEF\xBF\xBD");                  // overlong '/'
  CHECK(sanitize_text("\xED\xA0\x80") == "\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBD");  // surrogate
  CHECK(sanitize_text("\xF4\x90\x80\x80").find("\xEF\xBF\xBD") == 0);              // above U+10FFFF
  CHECK(sanitize_text("a\x1b[31mb") == "a\\x1B[31mb");
  CHECK(sanitize_text(std::string("n\0l", 3)) == "n\\x00l");
  CHECK(sanitize_text("a\r\nb\rc") == "a\nb\nc");
  CHECK(sanitize_text("\xC2\x85") == "\\u{0085}");      // C1 control (NEL)
  CHECK(sanitize_text("\xEF\xBF\xBE") == "\\u{FFFE}");  // not allowed in XML
  CHECK(sanitize_text("tab\tand\nnewline") == "tab\tand\nnewline");
  CHECK(sanitize_text("\xC3\xA9t\xC3\xA9 \xF0\x9F\x8E\xB1") ==
        "\xC3\xA9t\xC3\xA9 \xF0\x9F\x8E\xB1");
  // Every single byte value, alone and after a lead byte: always valid, never a control.
  for (int b = 0; b < 256; ++b)
    for (const std::string prefix : {"", "\xE2", "\xF0\x9F"}) {
      const std::string out = sanitize_text(prefix + std::string(1, static_cast<char>(b)));
      CAPTURE(b, prefix.size());
      CHECK(valid_utf8(out));
      CHECK_FALSE(has_control(out));
    }
}

TEST_CASE("BoundedText keeps the head and the tail, counts the rest") {
  BoundedText t(8, 4);
  for (int i = 0; i < 1000; ++i) t.append("0123456789");
  CHECK(t.total() == 10000);
  const std::string s = t.text();
  CHECK(s.rfind("01234567", 0) == 0);
  CHECK(s.find("[... 9988 bytes not shown ...]") != std::string::npos);
  CHECK(s.substr(s.size() - 4) == "6789");
  // A chunk larger than the tail, and small appends that wrap the ring.
  BoundedText u(0, 5);
  u.append(std::string(100, 'x') + "hello");
  u.append("ab");
  CHECK(u.text() == "\n[... 102 bytes not shown ...]\nlloab");
  BoundedText small(64, 64);
  small.append("short");
  CHECK(small.text() == "short");
}
