#include "core/output_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <system_error>

namespace fs = std::filesystem;

namespace pinsim {

std::string output_error_text(const fs::path& file, const char* what, int err) {
  return file.string() + ": cannot " + what + " (" +
         std::error_code(err, std::generic_category()).message() + ")";
}

int write_all(int fd, const char* data, std::size_t n) noexcept {
  while (n > 0) {
    const ssize_t w = ::write(fd, data, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    if (w == 0) return EIO;  // no progress and no error: never loop forever
    data += w;
    n -= static_cast<std::size_t>(w);
  }
  return 0;
}

void write_file_atomically(const fs::path& file, std::string_view bytes) {
  fs::path tmp = file;
  tmp += ".tmp." + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0) throw OutputError(output_error_text(file, "write", errno));
  int err = write_all(fd, bytes.data(), bytes.size());
  if (::close(fd) != 0 && err == 0) err = errno;
  if (err == 0 && ::rename(tmp.c_str(), file.c_str()) != 0) err = errno;
  if (err != 0) {
    ::unlink(tmp.c_str());
    throw OutputError(output_error_text(file, "write", err));
  }
}

LineFile::LineFile(fs::path file, std::string_view header) : path_(std::move(file)) {
  fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd_ < 0) throw OutputError(output_error_text(path_, "write", errno));
  append(header);
}

LineFile::~LineFile() {
  if (fd_ >= 0) ::close(fd_);
}

void LineFile::append(std::string_view lines) {
  if (fd_ < 0) throw OutputError(path_.string() + ": not written after an earlier failure");
  const int err = write_all(fd_, lines.data(), lines.size());
  if (err == 0) {
    size_ += static_cast<off_t>(lines.size());
    return;
  }
  // Drop the part of a line that made it to the file: the file ends with a whole line.
  // Shrinking needs no space, so this works on a full disk and under a file-size limit.
  const int trunc_err = ::ftruncate(fd_, size_) == 0 ? 0 : errno;
  ::close(fd_);
  fd_ = -1;
  std::string msg = output_error_text(path_, "write", err);
  if (trunc_err != 0)
    msg += "; could not cut it back to its last whole line either (" +
           std::error_code(trunc_err, std::generic_category()).message() + ")";
  throw OutputError(msg);
}

void LineFile::close() {
  if (fd_ < 0) return;
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) throw OutputError(output_error_text(path_, "close", errno));
}

}  // namespace pinsim
