// The walls cinevol-reader raises around itself (readers/sandbox.h): each
// test forks a child that enters them and tries one thing.
#include "io/readers/sandbox.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <functional>

#include "io/reader_cage.h"
#include "support/test_paths.h"

namespace cinevol {
namespace {

using testing::ScratchDir;
namespace fs = std::filesystem;

// Runs `attempt` in a forked child inside the walls, with `input` open as its
// one input; returns the child's wait status. The attempt's return value is
// the exit code.
int InTheCage(const fs::path& input, const fs::path& work_dir, const std::function<int(int fd)>& attempt) {
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = open(input.c_str(), O_RDONLY);
    reader::Enter({fd}, work_dir, 3);
    _exit(attempt(fd));
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

class ReaderSandbox : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(scratch_ / "work");
    std::ofstream(scratch_ / "input.txt") << "the input";
    std::ofstream(scratch_ / "other.txt") << "another file";
  }
  int Run(const std::function<int(int fd)>& attempt) {
    return InTheCage(scratch_ / "input.txt", scratch_ / "work", attempt);
  }
  bool KilledBySigsys(int status) { return WIFSIGNALED(status) && WTERMSIG(status) == SIGSYS; }

  ScratchDir scratch_;
};

TEST_F(ReaderSandbox, ReadsItsInputThroughTheDescriptorAndItsPath) {
  const int status = Run([](int fd) {
    char text[16] = {};
    if (pread(fd, text, 9, 0) != 9 || std::string(text) != "the input") return 1;
    const int again = open(("/proc/self/fd/" + std::to_string(fd)).c_str(), O_RDONLY);
    return again >= 0 && read(again, text, 9) == 9 ? 0 : 2;
  });
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
}

TEST_F(ReaderSandbox, OpensNoOtherFileWhereTheKernelHasLandlock) {
  if (!reader_cage::KernelHasLandlock()) GTEST_SKIP() << "no Landlock on this kernel: seccomp alone";
  const fs::path other = scratch_ / "other.txt";
  const int status = Run([&](int) { return open(other.c_str(), O_RDONLY) < 0 && errno == EACCES ? 0 : 1; });
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
}

TEST_F(ReaderSandbox, NoNetwork) {
  EXPECT_TRUE(KilledBySigsys(Run([](int) { return socket(AF_INET, SOCK_STREAM, 0) >= 0 ? 0 : 1; })));
}

TEST_F(ReaderSandbox, NoWritesByName) {
  const fs::path created = scratch_ / "work" / "written.txt";
  EXPECT_TRUE(KilledBySigsys(Run([&](int) { return open(created.c_str(), O_WRONLY | O_CREAT, 0600); })));
  EXPECT_FALSE(fs::exists(created));
  const fs::path other = scratch_ / "other.txt";
  EXPECT_TRUE(KilledBySigsys(Run([&](int) { return open(other.c_str(), O_RDWR); })));
}

TEST_F(ReaderSandbox, NoNewProgramsOrProcesses) {
  EXPECT_TRUE(KilledBySigsys(Run([](int) {
    char* argv[] = {const_cast<char*>("/bin/true"), nullptr};
    execv("/bin/true", argv);
    return 1;
  })));
  EXPECT_TRUE(KilledBySigsys(Run([](int) { return fork() >= 0 ? 0 : 1; })));
}

TEST_F(ReaderSandbox, NoExecutableMemoryAndNoRaisedLimits) {
  EXPECT_TRUE(KilledBySigsys(Run([](int) {
    return mmap(nullptr, 4096, PROT_READ | PROT_EXEC, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0) == MAP_FAILED ? 1 : 0;
  })));
  EXPECT_TRUE(KilledBySigsys(Run([](int) {
    rlimit unlimited{RLIM_INFINITY, RLIM_INFINITY};
    return setrlimit(RLIMIT_AS, &unlimited);
  })));
}

}  // namespace
}  // namespace cinevol
