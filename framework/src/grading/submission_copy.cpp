#include "grading/submission_copy.hpp"

#include <fcntl.h>
#include <linux/openat2.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace fs = std::filesystem;

namespace pinsim::grading {
namespace {

constexpr std::size_t kMaxListed = 50;

/// Closes a descriptor when it goes out of scope.
struct Fd {
  int fd = -1;
  explicit Fd(int f) : fd(f) {}
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
};

/// Copies an open regular file to `to` (created 0644); false on any error.
bool copy_fd(int in, const fs::path& to) {
  const int out = ::open(to.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOFOLLOW, 0644);
  bool ok = out >= 0;
  char buf[1 << 16];
  ssize_t n;
  while (ok && (n = ::read(in, buf, sizeof buf)) > 0)
    ok = ::write(out, buf, static_cast<std::size_t>(n)) == n;
  if (out >= 0) ok = ::close(out) == 0 && ok;
  return ok;
}

/// Why a file the grader could read is not the submitter's to give; "" if it is. The
/// submitter is the owner of the submission's top folder.
std::string foreign(const struct stat& st, uid_t owner) {
  if (st.st_uid == owner) return "";
  const std::string uid = std::to_string(st.st_uid);
  if (st.st_nlink > 1)
    return "a hard link to a file of another owner (uid " + uid +
           "): its contents are not the submission's";
  if ((st.st_mode & S_IROTH) == 0)
    return "a file of another owner (uid " + uid + ") that the submission's owner cannot read";
  return "";
}

std::string kind_of(mode_t m) {
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISSOCK(m)) return "a socket";
  if (S_ISCHR(m) || S_ISBLK(m)) return "a device";
  if (S_ISDIR(m)) return "a folder";
  return "not a regular file";
}

/// Opens `rel` below `root_fd`, following symlinks only while they stay below it; O_PATH, so
/// opening has no side effect whatever it is. -1 with errno EXDEV when the path leaves.
int open_beneath(int root_fd, const fs::path& rel) {
  open_how how{};
  how.flags = O_PATH | O_CLOEXEC;
  how.resolve = RESOLVE_BENEATH | RESOLVE_NO_MAGICLINKS;
  const long fd = ::syscall(SYS_openat2, root_fd, rel.c_str(), &how, sizeof how);
  return static_cast<int>(fd);
}

/// Where an O_PATH descriptor points, as the kernel resolved it.
fs::path fd_path(int fd) {
  std::error_code ec;
  return fs::read_symlink("/proc/self/fd/" + std::to_string(fd), ec);
}

bool inside(const fs::path& p, const fs::path& root) {
  const auto r = p.lexically_relative(root);
  return !r.empty() && *r.begin() != "..";
}

/// A symlink at `rel`: opened if it resolves inside the submission (openat2's
/// RESOLVE_BENEATH, or where the kernel lacks it, the canonical path), else -1 and why.
int follow_link(int root_fd, const fs::path& root, const fs::path& rel, std::string& why) {
  std::error_code ec;
  const fs::path target = fs::read_symlink(root / rel, ec);
  int fd = open_beneath(root_fd, rel);
  int err = fd < 0 ? errno : 0;
  if (fd < 0 && (err == EXDEV || err == ENOSYS || err == EPERM)) {
    // An absolute link back into the submission, or no openat2 here: resolve it and look.
    const fs::path canon = fs::weakly_canonical(root / rel, ec);
    if (ec || !inside(canon, root)) {
      err = EXDEV;
    } else if (!fs::exists(canon, ec)) {
      err = ENOENT;
    } else {
      fd = err == EXDEV ? open_beneath(root_fd, canon.lexically_relative(root))
                        : ::open(canon.c_str(), O_PATH | O_CLOEXEC | O_NOFOLLOW);
      err = fd < 0 ? errno : 0;
    }
  }
  if (fd < 0) {
    // A dangling link that would lead out is named for where it leads, not for being dangling.
    const fs::path lexical = (rel.parent_path() / target).lexically_normal();
    if (target.is_absolute() || (!lexical.empty() && *lexical.begin() == "..")) err = EXDEV;
    const std::string to = "a symlink to " + target.string();
    why = err == ENOENT  ? to + ", which does not exist"
          : err == ELOOP ? to + " in a loop"
          : err == EXDEV ? to + ", outside the submission"
                         : to + " that cannot be followed: " + std::strerror(err);
  }
  return fd;
}

/// Copies the file behind an O_PATH descriptor if it is a regular file of the submitter's.
void copy_path_fd(int path_fd, const fs::path& to, const std::string& shown, uid_t owner,
                  std::uintmax_t max_bytes, CopyLog& log) {
  struct stat st {};
  if (::fstat(path_fd, &st) != 0) return log.leave_out(shown, std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return log.leave_out(shown, kind_of(st.st_mode));
  if (const std::string why = foreign(st, owner); !why.empty()) return log.leave_out(shown, why);
  if (static_cast<std::uintmax_t>(st.st_size) > max_bytes)
    return log.leave_out(shown, "larger than " + std::to_string(max_bytes >> 20) + " MiB");
  const Fd in(::open(("/proc/self/fd/" + std::to_string(path_fd)).c_str(),
                     O_RDONLY | O_CLOEXEC | O_NONBLOCK));
  if (in.fd < 0)
    return log.leave_out(shown, std::string("cannot be read: ") + std::strerror(errno));
  if (!copy_fd(in.fd, to)) return log.leave_out(shown, "could not be copied");
  log.bytes += static_cast<std::uintmax_t>(st.st_size);
}

}  // namespace

void CopyLog::leave_out(const std::string& path, const std::string& why) {
  if (left_out.size() < kMaxListed) left_out.push_back(path + ": " + why);
  ++left_out_count;
}

std::string CopyLog::text() const {
  if (left_out_count == 0) return "";
  std::vector<std::string> sorted = left_out;  // the folder's order is the file system's
  std::sort(sorted.begin(), sorted.end());
  std::string s = "Left out of the copy of your submission that was built and graded (" +
                  std::to_string(left_out_count) + "):";
  for (const auto& l : sorted) s += "\n  " + l;
  if (left_out_count > left_out.size())
    s += "\n  ... and " + std::to_string(left_out_count - left_out.size()) + " more";
  return s;
}

bool copy_regular_file(const fs::path& from, const fs::path& to, std::uintmax_t max_bytes) {
  const Fd in(::open(from.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC | O_NONBLOCK));
  struct stat st {};
  if (in.fd < 0 || ::fstat(in.fd, &st) != 0 || !S_ISREG(st.st_mode) ||
      static_cast<std::uintmax_t>(st.st_size) > max_bytes)
    return false;
  return copy_fd(in.fd, to);
}

std::string copy_source_tree(const fs::path& from, const fs::path& to, std::uintmax_t max_bytes,
                             std::size_t max_entries, CopyLog& log) {
  std::error_code ec;
  const fs::path root = fs::canonical(from, ec);
  if (ec) return "cannot read the submission: " + ec.message();
  const Fd root_fd(::open(root.c_str(), O_PATH | O_DIRECTORY | O_CLOEXEC));
  struct stat root_st {};
  if (root_fd.fd < 0 || ::fstat(root_fd.fd, &root_st) != 0)
    return std::string("cannot read the submission: ") + std::strerror(errno);
  fs::create_directories(to, ec);
  for (auto it = fs::recursive_directory_iterator(
           root, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (++log.entries > max_entries)
      return "the submission has more than " + std::to_string(max_entries) + " files";
    const fs::path rel = it->path().lexically_relative(root);
    const fs::path dst = to / rel;
    const std::string shown = rel.string();
    struct stat lst {};
    if (::fstatat(root_fd.fd, rel.c_str(), &lst, AT_SYMLINK_NOFOLLOW) != 0) {
      log.leave_out(shown, std::strerror(errno));
      continue;
    }
    if (S_ISDIR(lst.st_mode)) {
      fs::create_directories(dst, ec);
      ec.clear();
    } else if (S_ISREG(lst.st_mode)) {
      const Fd f(::openat(root_fd.fd, rel.c_str(), O_PATH | O_NOFOLLOW | O_CLOEXEC));
      if (f.fd < 0)
        log.leave_out(shown, std::strerror(errno));
      else
        copy_path_fd(f.fd, dst, shown, root_st.st_uid, max_bytes - std::min(max_bytes, log.bytes),
                     log);
    } else if (S_ISLNK(lst.st_mode)) {
      std::string why;
      const Fd f(follow_link(root_fd.fd, root, rel, why));
      struct stat st {};
      if (f.fd < 0) {
        log.leave_out(shown, why);
      } else if (::fstat(f.fd, &st) == 0 && S_ISDIR(st.st_mode)) {
        // A folder inside: the same relative link in the copy (never walked twice).
        const fs::path target = fd_path(f.fd).lexically_relative(root);
        fs::create_symlink(target.lexically_relative(rel.parent_path()), dst, ec);
        if (ec) log.leave_out(shown, "a symlink that could not be recreated: " + ec.message());
        ec.clear();
      } else {
        copy_path_fd(f.fd, dst, shown, root_st.st_uid, max_bytes - std::min(max_bytes, log.bytes),
                     log);
      }
    } else {
      log.leave_out(shown, kind_of(lst.st_mode));
    }
    if (log.bytes > max_bytes)
      return "the submission is larger than " + std::to_string(max_bytes >> 20) + " MiB";
  }
  return ec ? "cannot read the submission: " + ec.message() : "";
}

int copy_libraries(const fs::path& dir, const fs::path& to, std::uintmax_t max_bytes,
                   CopyLog& log) {
  std::error_code ec;
  const fs::path root = fs::canonical(dir, ec);
  const Fd root_fd(ec ? -1 : ::open(root.c_str(), O_PATH | O_DIRECTORY | O_CLOEXEC));
  struct stat root_st {};
  if (root_fd.fd < 0 || ::fstat(root_fd.fd, &root_st) != 0) return 0;
  int n = 0;
  for (const auto& e : fs::directory_iterator(root, ec)) {
    if (e.path().extension() != ".so") continue;
    const fs::path rel = e.path().filename();
    std::string why;
    struct stat lst {};
    if (::fstatat(root_fd.fd, rel.c_str(), &lst, AT_SYMLINK_NOFOLLOW) != 0) continue;
    const Fd f(S_ISLNK(lst.st_mode)
                   ? follow_link(root_fd.fd, root, rel, why)
                   : ::openat(root_fd.fd, rel.c_str(), O_PATH | O_NOFOLLOW | O_CLOEXEC));
    if (f.fd < 0) {
      log.leave_out(rel.string(), why.empty() ? std::strerror(errno) : why);
      continue;
    }
    const std::size_t before = log.left_out_count;
    copy_path_fd(f.fd, to / rel, rel.string(), root_st.st_uid, max_bytes, log);
    n += log.left_out_count == before;
  }
  return n;
}

}  // namespace pinsim::grading
