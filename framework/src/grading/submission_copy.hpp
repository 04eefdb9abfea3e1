// Copying a submission into the grader's staging folder without reading more than the
// submission holds: the grader may run as root, so what it copies must be what the
// submitter could give. Regular files are copied when they are the submitter's (a hard link
// to another owner's file, or a file its owner cannot read, is left out), symlinks are
// followed only while they stay inside the submission (a link to a folder inside becomes a
// relative link in the copy), and FIFOs, sockets and devices are left out. Everything left
// out is listed, with the reason, for the student's feedback.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace pinsim::grading {

/// What one copy took and what it left out.
struct CopyLog {
  std::vector<std::string> left_out;  ///< "path: why", in the order met (at most kMaxListed)
  std::size_t left_out_count = 0;     ///< all of them, listed or not
  std::uintmax_t bytes = 0;           ///< bytes copied
  std::size_t entries = 0;            ///< files, folders and links met
  void leave_out(const std::string& path, const std::string& why);
  /// "" when nothing was left out; else a paragraph for the student listing it.
  std::string text() const;
};

/// Copies a source tree `from` into `to` (created). Returns "" or why the submission cannot
/// be graded at all (more than `max_entries` entries or `max_bytes` bytes, unreadable).
std::string copy_source_tree(const std::filesystem::path& from, const std::filesystem::path& to,
                             std::uintmax_t max_bytes, std::size_t max_entries, CopyLog& log);

/// Copies every `*.so` directly in `dir` (following symlinks that stay inside it) into `to`;
/// returns how many were copied. Each at most `max_bytes`.
int copy_libraries(const std::filesystem::path& dir, const std::filesystem::path& to,
                   std::uintmax_t max_bytes, CopyLog& log);

/// Copies one regular file without following a symlink at `from`; false if it is not one, it
/// is larger than `max_bytes`, or it cannot be read or written.
bool copy_regular_file(const std::filesystem::path& from, const std::filesystem::path& to,
                       std::uintmax_t max_bytes);

}  // namespace pinsim::grading
