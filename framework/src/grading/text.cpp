#include "grading/text.hpp"

#include <cstdint>
#include <cstdio>

namespace pinsim::grading {
namespace {

void hex_escape(std::string& out, unsigned value, bool unicode) {
  char buf[16];
  if (unicode)
    std::snprintf(buf, sizeof buf, "\\u{%04X}", value);
  else
    std::snprintf(buf, sizeof buf, "\\x%02X", value);
  out += buf;
}

void put_utf8(std::string& out, uint32_t cp) {
  if (cp < 0x80) {
    out += static_cast<char>(cp);
  } else if (cp < 0x800) {
    out += static_cast<char>(0xC0 | (cp >> 6));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else if (cp < 0x10000) {
    out += static_cast<char>(0xE0 | (cp >> 12));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else {
    out += static_cast<char>(0xF0 | (cp >> 18));
    out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  }
}

constexpr uint32_t kReplacement = 0xFFFD;

/// Decodes one code point at s[i]; returns its length, or 0 if the bytes there are not a
/// valid, shortest-form UTF-8 sequence (RFC 3629: no surrogates, nothing above U+10FFFF).
std::size_t decode(std::string_view s, std::size_t i, uint32_t& cp) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[i + k]); };
  const unsigned char c = b(0);
  std::size_t len;
  uint32_t min;
  if (c < 0x80) {
    cp = c;
    return 1;
  } else if ((c & 0xE0) == 0xC0) {
    len = 2, cp = c & 0x1F, min = 0x80;
  } else if ((c & 0xF0) == 0xE0) {
    len = 3, cp = c & 0x0F, min = 0x800;
  } else if ((c & 0xF8) == 0xF0) {
    len = 4, cp = c & 0x07, min = 0x10000;
  } else {
    return 0;
  }
  if (i + len > s.size()) return 0;
  for (std::size_t k = 1; k < len; ++k) {
    if ((b(k) & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (b(k) & 0x3F);
  }
  if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  return len;
}

}  // namespace

std::string sanitize_text(std::string_view raw) {
  std::string out;
  out.reserve(raw.size());
  for (std::size_t i = 0; i < raw.size();) {
    uint32_t cp = 0;
    const std::size_t len = decode(raw, i, cp);
    if (len == 0) {
      put_utf8(out, kReplacement);
      ++i;
      continue;
    }
    i += len;
    if (cp == '\n' || cp == '\t') {
      out += static_cast<char>(cp);
    } else if (cp == '\r') {
      if (i < raw.size() && raw[i] == '\n') continue;  // "\r\n" -> "\n"
      out += '\n';
    } else if (cp < 0x20 || cp == 0x7F) {
      hex_escape(out, cp, false);
    } else if ((cp >= 0x80 && cp <= 0x9F) || cp == 0xFFFE || cp == 0xFFFF) {
      hex_escape(out, cp, true);
    } else {
      put_utf8(out, cp);
    }
  }
  return out;
}

void BoundedText::append(const char* data, std::size_t n) {
  total_ += n;
  const std::size_t to_head = std::min(n, head_limit_ - std::min(head_limit_, head_.size()));
  head_.append(data, to_head);
  data += to_head;
  n -= to_head;
  if (tail_limit_ == 0 || n == 0) return;
  if (n >= tail_limit_) {  // only the last tail_limit_ bytes of this chunk can survive
    tail_.assign(data + n - tail_limit_, tail_limit_);
    tail_pos_ = 0;
    return;
  }
  for (std::size_t k = 0; k < n; ++k) {
    if (tail_.size() < tail_limit_) {
      tail_ += data[k];
    } else {
      tail_[tail_pos_] = data[k];
      tail_pos_ = (tail_pos_ + 1) % tail_limit_;
    }
  }
}

std::string BoundedText::text() const {
  std::string tail = tail_.substr(tail_pos_) + tail_.substr(0, tail_pos_);
  const std::size_t dropped = total_ - head_.size() - tail.size();
  std::string out = sanitize_text(head_);
  if (dropped > 0) out += "\n[... " + std::to_string(dropped) + " bytes not shown ...]\n";
  out += sanitize_text(tail);
  return out;
}

}  // namespace pinsim::grading
