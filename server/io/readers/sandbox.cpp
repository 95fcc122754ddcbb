// Limits, Landlock and seccomp for cinevol-reader.
#include "io/readers/sandbox.h"

#include <fcntl.h>
#include <linux/landlock.h>
#include <seccomp.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

namespace cinevol::reader {
namespace {

// The most a rewritten header may take on disk (a list of 8192 files).
constexpr rlim_t kMaxScratchBytes = 16 << 20;

void Limit(int resource, rlim_t soft, rlim_t hard) {
  const rlimit limit{soft, hard};
  if (setrlimit(resource, &limit) != 0) {
    throw std::runtime_error(std::string("cannot set a limit: ") + std::strerror(errno));
  }
}

// Writes "forbidden system call N" to stderr, then dies of SIGSYS: the parent
// sees the signal, the log the call.
void OnForbiddenCall(int, siginfo_t* info, void*) {
  char text[64];
  const int n = std::snprintf(text, sizeof text, "forbidden system call %d\n", info->si_syscall);
  if (n > 0 && write(2, text, std::size_t(n)) < 0) {
    // nothing more to say
  }
  signal(SIGSYS, SIG_DFL);
  raise(SIGSYS);
}

// Landlock: reading `inputs` and the work folder, nothing else. Returns
// false where the kernel has no Landlock, or a container's seccomp profile
// forbids it (then seccomp walls the reader in alone; stderr says why).
bool RestrictFiles(const std::vector<int>& inputs, const std::filesystem::path& work_dir) {
  const long abi = syscall(SYS_landlock_create_ruleset, nullptr, 0, LANDLOCK_CREATE_RULESET_VERSION);
  if (abi < 1) return false;
  // Every right this kernel knows: unhandled ones would stay allowed.
  const int rights = abi >= 5 ? 16 : abi >= 3 ? 15 : abi >= 2 ? 14 : 13;
  struct {
    __u64 handled_access_fs;
  } attr{(__u64{1} << rights) - 1};
  const int ruleset = int(syscall(SYS_landlock_create_ruleset, &attr, sizeof attr, 0));
  const int dir = open(work_dir.c_str(), O_PATH | O_DIRECTORY | O_CLOEXEC);
  bool ok = ruleset >= 0 && dir >= 0;
  auto allow = [&](int fd, __u64 access) {
    landlock_path_beneath_attr rule{access, fd};
    // EBADFD: no path leads to it (a memfd); it is read through its descriptor.
    if (syscall(SYS_landlock_add_rule, ruleset, LANDLOCK_RULE_PATH_BENEATH, &rule, 0) != 0 && errno != EBADFD) {
      ok = false;
    }
  };
  for (std::size_t i = 0; ok && i < inputs.size(); ++i) allow(inputs[i], LANDLOCK_ACCESS_FS_READ_FILE);
  if (ok) allow(dir, LANDLOCK_ACCESS_FS_READ_FILE | LANDLOCK_ACCESS_FS_READ_DIR);
  ok = ok && syscall(SYS_landlock_restrict_self, ruleset, 0) == 0;
  if (!ok) std::fprintf(stderr, "landlock not applied (%s): seccomp alone\n", std::strerror(errno));
  if (dir >= 0) close(dir);
  if (ruleset >= 0) close(ruleset);
  return ok;
}

void Allow(scmp_filter_ctx ctx, const char* name, std::vector<scmp_arg_cmp> args = {}) {
  const int nr = seccomp_syscall_resolve_name(name);
  if (nr == __NR_SCMP_ERROR) return;  // not on this architecture
  if (seccomp_rule_add_array(ctx, SCMP_ACT_ALLOW, nr, unsigned(args.size()), args.data()) != 0) {
    throw std::runtime_error(std::string("seccomp rule for ") + name);
  }
}

void Refuse(scmp_filter_ctx ctx, const char* name, int error) {
  const int nr = seccomp_syscall_resolve_name(name);
  if (nr != __NR_SCMP_ERROR) seccomp_rule_add(ctx, SCMP_ACT_ERRNO(error), nr, 0);
}

void FilterSystemCalls(int channel_fd) {
  struct sigaction action {};
  action.sa_sigaction = OnForbiddenCall;
  action.sa_flags = SA_SIGINFO;
  sigaction(SIGSYS, &action, nullptr);

  scmp_filter_ctx ctx = seccomp_init(SCMP_ACT_TRAP);
  if (!ctx) throw std::runtime_error("seccomp_init");
  for (const char* name :
       {"read", "readv", "pread64", "preadv", "preadv2", "write", "writev", "pwrite64", "lseek", "close", "fstat",
        "newfstatat", "statx", "stat", "lstat", "readlink", "readlinkat", "getcwd", "access", "faccessat",
        "faccessat2", "getdents64", "fcntl", "dup", "dup2", "dup3", "ftruncate", "fadvise64", "munmap", "mremap",
        "madvise", "brk", "futex", "set_robust_list", "get_robust_list", "rseq", "sched_yield", "sched_getaffinity",
        "getrandom", "clock_gettime", "clock_getres", "gettimeofday", "time", "nanosleep", "clock_nanosleep",
        "getpid", "gettid", "getppid", "getuid", "geteuid", "getgid", "getegid", "uname", "sysinfo", "getrlimit",
        "rt_sigaction", "rt_sigprocmask", "rt_sigreturn", "sigaltstack", "poll", "ppoll", "exit", "exit_group"}) {
    Allow(ctx, name);
  }
  // Reading only: nothing created, truncated, appended or written by name.
  const scmp_datum_t writes = O_ACCMODE | O_CREAT | O_TRUNC | O_APPEND | 020000000 /* __O_TMPFILE */;
  Allow(ctx, "openat", {SCMP_A2(SCMP_CMP_MASKED_EQ, writes, 0)});
  Allow(ctx, "open", {SCMP_A1(SCMP_CMP_MASKED_EQ, writes, 0)});
  // Memory, never executable.
  Allow(ctx, "mmap", {SCMP_A2(SCMP_CMP_MASKED_EQ, PROT_EXEC, 0)});
  Allow(ctx, "mprotect", {SCMP_A2(SCMP_CMP_MASKED_EQ, PROT_EXEC, 0)});
  // Threads only, no processes; glibc falls back from clone3 to clone.
  Allow(ctx, "clone", {SCMP_A0(SCMP_CMP_MASKED_EQ, CLONE_THREAD, CLONE_THREAD)});
  Refuse(ctx, "clone3", ENOSYS);
  // Limits read, never raised; signals to itself only (abort()).
  Allow(ctx, "prlimit64", {SCMP_A2(SCMP_CMP_EQ, 0)});
  Allow(ctx, "tgkill", {SCMP_A0(SCMP_CMP_EQ, scmp_datum_t(getpid()))});
  Allow(ctx, "kill", {SCMP_A0(SCMP_CMP_EQ, scmp_datum_t(getpid()))});
  // The parent's socket, and no other.
  for (const char* name : {"sendmsg", "recvmsg", "sendto", "recvfrom"}) {
    Allow(ctx, name, {SCMP_A0(SCMP_CMP_EQ, scmp_datum_t(channel_fd))});
  }
  Refuse(ctx, "ioctl", ENOTTY);  // isatty() and the like: not a terminal
  const int loaded = seccomp_load(ctx);
  seccomp_release(ctx);
  if (loaded != 0) throw std::runtime_error(std::string("seccomp_load: ") + std::strerror(-loaded));
}

}  // namespace

void SetLimits(std::uint64_t address_space, std::uint64_t address_space_max, int cpu_seconds) {
  Limit(RLIMIT_CORE, 0, 0);
  Limit(RLIMIT_CPU, rlim_t(cpu_seconds), rlim_t(cpu_seconds) + 1);
  Limit(RLIMIT_AS, rlim_t(address_space), rlim_t(std::max(address_space, address_space_max)));
  signal(SIGXFSZ, SIG_IGN);  // past the size: EFBIG, not death
  Limit(RLIMIT_FSIZE, kMaxScratchBytes, kMaxScratchBytes);
  rlimit files{};
  if (getrlimit(RLIMIT_NOFILE, &files) == 0) Limit(RLIMIT_NOFILE, files.rlim_max, files.rlim_max);
}

bool Enter(const std::vector<int>& inputs, const std::filesystem::path& work_dir, int channel_fd) {
  if (prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) != 0) throw std::runtime_error("PR_SET_NO_NEW_PRIVS");
  const bool landlocked = RestrictFiles(inputs, work_dir);
  FilterSystemCalls(channel_fd);
  return landlocked;
}

}  // namespace cinevol::reader
