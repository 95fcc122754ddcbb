// The server's upload folder (runtime/upload_folder.h): private and removed
// with the server; one left by a server that was killed is removed by the
// next to start, one held by a running server is not.
#include "runtime/upload_folder.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>

#include <fstream>

#include "service/server_process.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;

TEST(UploadFolder, IsPrivateAndGoesWithItsOwner) {
  fs::path path;
  {
    service::UploadFolder folder;
    path = folder.path();
    EXPECT_EQ(path.parent_path(), fs::temp_directory_path());
    EXPECT_EQ(path.filename().string().rfind(fmt::format("cinevol-uploads-{}-", getpid()), 0), 0u) << path;
    struct stat info {};
    ASSERT_EQ(lstat(path.c_str(), &info), 0);
    EXPECT_TRUE(S_ISDIR(info.st_mode));
    EXPECT_EQ(info.st_mode & 0777, 0700u);
    std::ofstream(path / "upload.nrrd") << "voxels";
  }
  EXPECT_FALSE(fs::exists(path));
}

TEST(UploadFolder, OneLeftUnlockedIsRemovedAndOneHeldIsKept) {
  service::UploadFolder running;  // another server's, alive
  const fs::path left = fs::temp_directory_path() / fmt::format("cinevol-uploads-{}-left", getpid());
  fs::create_directories(left / "series");
  std::ofstream(left / "series" / "1.dcm") << "pixels";
  {
    service::UploadFolder starting;
    EXPECT_NE(starting.path(), running.path());
  }
  EXPECT_FALSE(fs::exists(left)) << "a dead server's uploads stay in the temporary folder";
  EXPECT_TRUE(fs::is_directory(running.path())) << "a running server's uploads were removed";
}

// For real: a server killed outright leaves its folder; the next server started removes it.
TEST(UploadFolder, AKilledServersFolderIsRemovedByTheNextServer) {
  ScratchDir scratch;
  fs::create_directories(scratch / "a");
  fs::create_directories(scratch / "b");
  auto killed = std::make_unique<ServerProcess>(scratch / "a");
  ASSERT_TRUE(killed->running()) << killed->Log();
  const std::vector<fs::path> left = TemporaryFilesNamed(fmt::format("cinevol-uploads-{}-", killed->pid()));
  ASSERT_EQ(left.size(), 1u);
  ASSERT_EQ(kill(killed->pid(), SIGKILL), 0);
  killed.reset();
  // (Under the whole suite another test's server may be the next to start: either removes it.)
  ServerProcess next(scratch / "b");
  ASSERT_TRUE(next.running()) << next.Log();
  EXPECT_FALSE(fs::exists(left.front())) << next.Log();
  const std::vector<fs::path> own = TemporaryFilesNamed(fmt::format("cinevol-uploads-{}-", next.pid()));
  ASSERT_EQ(own.size(), 1u);
  EXPECT_EQ(next.Stop(), 0);
  EXPECT_FALSE(fs::exists(own.front())) << "a server stopped by SIGTERM removes its own";
}

}  // namespace
}  // namespace cinevol::testing
