// Writing output files so that a failed write is an error and never leaves a broken file:
// every write, flush and close checked (partial writes and EINTR retried), CSVs written in
// whole lines only, small files replaced atomically.
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>

namespace pinsim {

/// An output file could not be written: the message names the file and the system's reason
/// ("out/trajectory.csv: cannot write (No space left on device)"). `pinsim` exits 1.
class OutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// "FILE: cannot WHAT (errno's text)".
std::string output_error_text(const std::filesystem::path& file, const char* what, int err);

/// Writes all `n` bytes to `fd`, continuing after partial writes and retrying on EINTR.
/// Returns 0, or the errno of the write that failed. Async-signal-safe.
int write_all(int fd, const char* data, std::size_t n) noexcept;

/// Writes `bytes` to a temporary file beside `file` (FILE.tmp.PID), then renames it over
/// `file`, so a reader sees the old file or the whole new one, never a part. Every write,
/// close and the rename are checked; on failure the temporary is removed, `file` is left as it
/// was, and OutputError names `file`. The folder must exist.
void write_file_atomically(const std::filesystem::path& file, std::string_view bytes);

/// An output file written in whole lines (a CSV): created (truncated) with its header; each
/// append is whole lines. A failed append truncates the file back to the last whole line
/// written, closes it and throws OutputError; later appends are refused.
class LineFile {
 public:
  /// Creates `file` and writes `header` (whole lines). Throws OutputError.
  LineFile(std::filesystem::path file, std::string_view header);
  ~LineFile();
  LineFile(const LineFile&) = delete;
  LineFile& operator=(const LineFile&) = delete;

  /// Appends whole lines (`lines` ends with '\n'). Throws OutputError.
  void append(std::string_view lines);
  /// Closes the file, checking the close. Throws OutputError. Does nothing once closed.
  void close();

  const std::filesystem::path& path() const { return path_; }
  /// Bytes of whole lines written so far.
  off_t size() const { return size_; }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  off_t size_ = 0;
};

}  // namespace pinsim
