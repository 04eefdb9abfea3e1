#include "grading/submission.hpp"

#include <fcntl.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <stdexcept>

#include "grading/submission_copy.hpp"

namespace fs = std::filesystem;

namespace pinsim::grading {
namespace {

constexpr std::uintmax_t kMaxLibrary = 256ull << 20;      // bytes per library
constexpr std::uintmax_t kMaxSourceBytes = 256ull << 20;  // a source submission in all
constexpr std::size_t kMaxSourceFiles = 20000;
constexpr std::size_t kLogHead = 24 << 10, kLogTail = 24 << 10;  // of a build's output

/// Every built library under `dir` (not following links) copied into `lib`.
int collect_libraries(const fs::path& dir, const fs::path& lib) {
  int n = 0;
  std::error_code ec;
  for (auto it =
           fs::recursive_directory_iterator(dir, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (it->path().extension() != ".so" || !fs::is_regular_file(it->symlink_status(ec))) continue;
    n += copy_regular_file(it->path(), lib / it->path().filename(), kMaxLibrary);
  }
  return n;
}

/// Read-only mounts of the SDK (headers, CMake package and the pinsim::scene_field archive)
/// at their own paths.
std::vector<Mount> sdk_mounts(const fs::path& prefix) {
  std::vector<Mount> m;
  std::error_code ec;
  for (const fs::path& p :
       {prefix / "lib/cmake/pinsim", prefix / "include/pinsim",
        prefix / "lib/libpinsim_scene_field.a", fs::path(PINSIM_SOURCE_DIR) / "framework/include"})
    if (fs::exists(p, ec)) m.push_back({p.string(), p.string(), false});
  return m;
}

/// Readable (mode) by this grader's sandbox uid and no other: a folder of root's with the
/// sandbox's group, so that another grade's submission beside this one cannot read it
/// (without namespaces every staging folder is in the same /tmp). Not root: the grader's own.
void private_to_sandbox(const fs::path& p, mode_t root_mode, mode_t own_mode) {
  if (::geteuid() == 0 && ::chown(p.c_str(), 0, sandbox_ids().second) != 0)
    throw std::runtime_error("chown " + p.string() + ": " + std::strerror(errno));
  ::chmod(p.c_str(), ::geteuid() == 0 ? root_mode : own_mode);
}

void own_for_sandbox(const fs::path& p) {
  const auto [uid, gid] = sandbox_ids();
  if (::geteuid() == 0 && ::chown(p.c_str(), uid, gid) != 0)
    throw std::runtime_error("chown " + p.string() + ": " + std::strerror(errno));
}

void chown_tree(const fs::path& p) {
  own_for_sandbox(p);
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(p, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    const auto [uid, gid] = sandbox_ids();
    if (::geteuid() == 0) ::lchown(it->path().c_str(), uid, gid);
  }
}

}  // namespace

PreparedSubmission::~PreparedSubmission() {
  if (staging.empty()) return;
  std::error_code ec;
  // A submission may have left folders without permissions in its build folder.
  for (auto it = fs::recursive_directory_iterator(
           staging, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
    if (fs::is_directory(it->symlink_status(ec))) ::chmod(it->path().c_str(), 0700);
  fs::remove_all(staging, ec);
}

void prepare_submission(const fs::path& submission, const fs::path& sdk_prefix,
                        const Rubric& rubric, PreparedSubmission& out) {
  const auto start = std::chrono::steady_clock::now();
  const char* tmp = std::getenv("TMPDIR");
  std::string templ = std::string(tmp && *tmp ? tmp : "/tmp") + "/pinsim-grade-XXXXXX";
  if (::mkdtemp(templ.data()) == nullptr)
    throw std::runtime_error("cannot make a staging folder in " + templ + ": " +
                             std::strerror(errno));
  out.staging = templ;
  out.libraries = out.staging / "lib";
  fs::create_directories(out.libraries);
  private_to_sandbox(out.staging, 0710, 0711);
  private_to_sandbox(out.libraries, 0750, 0755);

  std::error_code ec;
  const fs::path& sub = submission;
  if (!fs::exists(sub, ec)) {
    out.problem = "the submission " + sub.filename().string() + " does not exist";
    return;
  }
  if (fs::is_regular_file(sub, ec)) {
    if (!copy_regular_file(sub, out.libraries / sub.filename(), kMaxLibrary))
      out.problem = "cannot read the submitted library " + sub.filename().string();
  } else if (fs::exists(sub / "CMakeLists.txt", ec)) {
    const fs::path work = out.staging / "work";
    fs::create_directories(work / "build");
    CopyLog log;
    const std::string copied =
        copy_source_tree(sub, work / "src", kMaxSourceBytes, kMaxSourceFiles, log);
    out.copy_notes = log.text();
    if (!copied.empty()) {
      out.problem = copied;
      return;
    }
    chown_tree(work);
    SandboxSpec spec;
    spec.limits = rubric.build_limits;
    spec.mounts = sdk_mounts(sdk_prefix);
    spec.mounts.push_back({work.string(), "/submission", true});
    spec.cwd = "/submission/build";
    // pinsim_DIR names the package's folder, so CMake need not list the folders above it
    // (outside a mount namespace the sandbox may not).
    const auto conf =
        run_sandboxed({"/usr/bin/cmake", "-S", "/submission/src", "-B", "/submission/build",
                       "-DCMAKE_BUILD_TYPE=Release", "-DCMAKE_PREFIX_PATH=" + sdk_prefix.string(),
                       "-Dpinsim_DIR=" + (sdk_prefix / "lib/cmake/pinsim").string()},
                      spec, kLogHead, kLogTail);
    const std::string conf_fail = conf.end.failure(spec.limits);
    if (!conf_fail.empty()) {
      out.problem = "the submission does not configure with CMake: the configure step " +
                    conf_fail + " (limits: docs/grading.md)\n" + conf.printed;
      out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      return;
    }
    // -k: keep going, so every plugin that compiles is built and graded.
    const auto build = run_sandboxed({"/usr/bin/cmake", "--build", "/submission/build", "--", "-k"},
                                     spec, kLogHead, kLogTail);
    const std::string build_fail = build.end.failure(spec.limits);
    collect_libraries(work / "build", out.libraries);
    if (!build_fail.empty())
      out.build_log =
          "the submission does not compile: the build " + build_fail + "\n" + build.printed;
  } else if (fs::is_directory(sub, ec)) {
    CopyLog log;
    copy_libraries(sub, out.libraries, kMaxLibrary, log);
    out.copy_notes = log.text();
  }
  bool any = false;
  for (const auto& e : fs::directory_iterator(out.libraries, ec))
    any = any || e.path().extension() == ".so";
  if (!any && out.problem.empty())
    out.problem =
        !out.build_log.empty()
            ? out.build_log
            : "the submission holds no plugin library (.so) and no CMakeLists.txt to build one";
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void stage_worker_program(const fs::path& exe, PreparedSubmission& out) {
  out.worker_program = exe;
  if (sandbox_mode() != SandboxMode::Fallback || out.staging.empty()) return;
  const fs::path dir = out.staging / "bin";
  fs::create_directories(dir);
  private_to_sandbox(dir, 0750, 0755);
  const fs::path copy = dir / "pinsim";
  if (!copy_regular_file(exe, copy, kMaxLibrary * 4) || ::chmod(copy.c_str(), 0755) != 0)
    throw std::runtime_error("cannot copy " + exe.string() + " into " + dir.string());
  out.worker_program = copy;
}

}  // namespace pinsim::grading
