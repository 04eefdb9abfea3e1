// container_like [--no-landlock] [--uid N] -- COMMAND ARGS...
// Runs COMMAND as a process of a Docker container with Docker's defaults would: no new
// namespaces (a seccomp filter answers unshare, setns, mount and clone with any namespace
// flag with EPERM and clone3 with ENOSYS, as Docker's default profile does) and only
// Docker's default capabilities. --no-landlock also answers Landlock's calls with ENOSYS (an
// older kernel or container runtime); --uid N runs COMMAND as uid and gid N instead of root.
// The grader's tests run `pinsim grade` under it to check its fallback sandbox.
#include <grp.h>
#include <linux/audit.h>
#include <linux/capability.h>
#include <linux/filter.h>
#include <linux/seccomp.h>
#include <sched.h>
#include <sys/prctl.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

#if defined(__x86_64__)
constexpr uint32_t kArch = AUDIT_ARCH_X86_64;
#elif defined(__aarch64__)
constexpr uint32_t kArch = AUDIT_ARCH_AARCH64;
#else
#error "container_like: no seccomp architecture for this machine"
#endif

constexpr uint32_t kNamespaceFlags = CLONE_NEWNS | CLONE_NEWCGROUP | CLONE_NEWUTS | CLONE_NEWIPC |
                                     CLONE_NEWUSER | CLONE_NEWPID | CLONE_NEWNET;

// Docker's default capability set (CHOWN, DAC_OVERRIDE, FOWNER, FSETID, KILL, SETGID, SETUID,
// SETPCAP, NET_BIND_SERVICE, NET_RAW, SYS_CHROOT, MKNOD, AUDIT_WRITE, SETFCAP).
constexpr int kDockerCaps[] = {
    CAP_CHOWN,      CAP_DAC_OVERRIDE, CAP_FOWNER,      CAP_FSETID,           CAP_KILL,
    CAP_SETGID,     CAP_SETUID,       CAP_SETPCAP,     CAP_NET_BIND_SERVICE, CAP_NET_RAW,
    CAP_SYS_CHROOT, CAP_MKNOD,        CAP_AUDIT_WRITE, CAP_SETFCAP};

std::vector<sock_filter> program(bool no_landlock) {
  std::vector<sock_filter> f;
  const auto stmt = [&](uint16_t code, uint32_t k) { f.push_back(BPF_STMT(code, k)); };
  const auto jeq = [&](uint32_t k, uint8_t jt, uint8_t jf) {
    f.push_back(BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, k, jt, jf));
  };
  const auto deny = [&](long nr, int err) {
    jeq(static_cast<uint32_t>(nr), 0, 1);
    stmt(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | static_cast<uint32_t>(err));
  };
  stmt(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, arch));
  jeq(kArch, 1, 0);
  stmt(BPF_RET | BPF_K, SECCOMP_RET_KILL_PROCESS);
  stmt(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, nr));
  for (const long nr : {SYS_unshare, SYS_setns, SYS_mount, SYS_umount2, SYS_pivot_root})
    deny(nr, EPERM);
  deny(SYS_clone3, ENOSYS);  // glibc then falls back to clone, whose flags are visible here
  if (no_landlock)
    for (const long nr : {444L, 445L, 446L}) deny(nr, ENOSYS);  // landlock_*
  // clone: allowed without namespace flags (the low word of the first argument).
  jeq(SYS_clone, 0, 4);
  stmt(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, args[0]));
  stmt(BPF_ALU | BPF_AND | BPF_K, kNamespaceFlags);
  jeq(0, 1, 0);
  stmt(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EPERM);
  stmt(BPF_RET | BPF_K, SECCOMP_RET_ALLOW);
  return f;
}

[[noreturn]] void die(const char* what) {
  std::fprintf(stderr, "container_like: %s: %s\n", what, std::strerror(errno));
  std::exit(125);
}

}  // namespace

int main(int argc, char** argv) {
  bool no_landlock = false;
  long uid = -1;
  int i = 1;
  for (; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--no-landlock") {
      no_landlock = true;
    } else if (a == "--uid" && i + 1 < argc) {
      uid = std::atol(argv[++i]);
    } else if (a == "--") {
      ++i;
      break;
    } else {
      std::fprintf(stderr, "usage: container_like [--no-landlock] [--uid N] -- COMMAND...\n");
      return 125;
    }
  }
  if (i >= argc) return 125;
  std::vector<sock_filter> f = program(no_landlock);
  sock_fprog prog{static_cast<unsigned short>(f.size()), f.data()};
  // Installed while CAP_SYS_ADMIN is still held, as the container runtime does; no
  // no_new_privs, which Docker does not set by default either.
  if (::prctl(PR_SET_SECCOMP, SECCOMP_MODE_FILTER, &prog) != 0) die("seccomp");
  for (int cap = 0; cap <= CAP_LAST_CAP; ++cap) {
    bool keep = false;
    for (int c : kDockerCaps) keep = keep || c == cap;
    if (!keep && ::prctl(PR_CAPBSET_DROP, cap, 0, 0, 0) != 0 && errno != EINVAL)
      die("PR_CAPBSET_DROP");
  }
  if (uid >= 0) {
    if (::setgroups(0, nullptr) != 0 || ::setresgid(uid, uid, uid) != 0 ||
        ::setresuid(uid, uid, uid) != 0)
      die("setresuid");
  } else {
    // Root keeps Docker's set now and, through the bounding set, after exec.
    __user_cap_header_struct hdr{_LINUX_CAPABILITY_VERSION_3, 0};
    __user_cap_data_struct data[2] = {};
    for (int c : kDockerCaps) {
      data[c / 32].effective |= 1u << (c % 32);
      data[c / 32].permitted |= 1u << (c % 32);
    }
    if (::syscall(SYS_capset, &hdr, data) != 0) die("capset");
  }
  ::execvp(argv[i], argv + i);
  die(argv[i]);
}
