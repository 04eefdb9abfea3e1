// Text that came from a submission, made safe to show: valid UTF-8, no control characters,
// bounded in size. Everything a submission prints or a compiler says passes through here
// before it reaches results.json, junit.xml or summary.txt.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace pinsim::grading {

/// Valid UTF-8 with only printable characters, '\n' and '\t': each invalid byte (a cut
/// multi-byte sequence, an overlong form, a surrogate) becomes U+FFFD; "\r\n" becomes "\n";
/// other control characters (C0, DEL, C1) and the XML-forbidden U+FFFE/U+FFFF are written as
/// the visible text "\xHH" or "\u{HHHH}". The result is valid in JSON and in XML 1.0.
std::string sanitize_text(std::string_view raw);

/// Keeps the first `head` and the last `tail` bytes of a stream of any length, and counts
/// the rest: memory stays bounded however much is appended.
class BoundedText {
 public:
  BoundedText(std::size_t head, std::size_t tail) : head_limit_(head), tail_limit_(tail) {}
  void append(const char* data, std::size_t n);
  void append(std::string_view s) { append(s.data(), s.size()); }
  std::size_t total() const { return total_; }
  bool empty() const { return total_ == 0; }
  /// The kept text, sanitized, with "[... N bytes not shown ...]" where bytes were dropped.
  std::string text() const;

 private:
  std::size_t head_limit_, tail_limit_;
  std::string head_, tail_;  // tail_ is a ring of the last bytes, rotated on read
  std::size_t tail_pos_ = 0, total_ = 0;
};

}  // namespace pinsim::grading
