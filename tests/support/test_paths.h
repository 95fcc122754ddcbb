// Where tests find the real data sets (../shared/data beside the checkout)
// and a fresh scratch folder per test.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

namespace cinevol::testing {

inline std::filesystem::path SharedData() { return CINEVOL_SHARED_DATA; }

// Skips the calling test when the shared data sets are absent.
#define CINEVOL_REQUIRE_SHARED_DATA()                                                       \
  do {                                                                                      \
    if (!std::filesystem::is_directory(::cinevol::testing::SharedData()))                  \
      GTEST_SKIP() << "real data not found at " << ::cinevol::testing::SharedData()         \
                   << " (../shared/data beside the checkout); skipping";                    \
  } while (0)

// An empty folder for this test, removed when it ends.
class ScratchDir {
 public:
  ScratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    // The process id too: two checkouts running their suites at once must not share one.
    path_ = std::filesystem::temp_directory_path() / (std::string("cinevol-") + info->test_suite_name() + "-" +
                                                      info->name() + "-" + std::to_string(::getpid()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() { std::filesystem::remove_all(path_); }
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// What the temporary folder holds whose name begins with `prefix` (a process's own files, left behind or not).
inline std::vector<std::filesystem::path> TemporaryFilesNamed(const std::string& prefix) {
  std::vector<std::filesystem::path> found;
  for (const auto& entry : std::filesystem::directory_iterator(std::filesystem::temp_directory_path())) {
    if (entry.path().filename().string().rfind(prefix, 0) == 0) found.push_back(entry.path());
  }
  return found;
}

}  // namespace cinevol::testing
