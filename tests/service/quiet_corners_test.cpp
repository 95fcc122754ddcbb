// Small things a new user meets at once (issue 32, "quiet corners"): a scene
// without lights is lit by the volume's default lights, not left black; a
// message about a file in a folder quotes the file's whole path.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;

TEST(QuietCorners, ASceneWithoutLightsTakesTheVolumesDefaultLights) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  v1::CreateSessionRequest request = SmallSession();
  request.mutable_scene()->mutable_transfer_function()->set_preset("ct-bone");  // and no lights
  const v1::CreateSessionResponse created = client.CreateSession(request);
  ASSERT_EQ(created.scene().lights_size(), 2) << "the answer shows the lights the session took";
  EXPECT_TRUE(created.scene().lights(0).has_area());
  EXPECT_TRUE(created.scene().lights(1).has_environment());
  auto stream = client.Attach(created.session_id());
  const auto frame = WaitFinal(*stream);
  ASSERT_TRUE(frame) << server.Log();
  EXPECT_GT(MeanLevel(Decode(*frame)), 10) << "a black frame: the scene is unlit";
}

// The server names a file it loads as "path 'DIR'"; a file in that folder
// is 'DIR/FILE', quoted whole (not 'DIR'/FILE).
TEST(QuietCorners, AMessageQuotesAFilesWholePath) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir scratch;
  const fs::path dup = scratch / "roots" / "dup";
  fs::create_directories(dup);
  std::vector<fs::path> slices;
  for (const auto& e : fs::directory_iterator(SharedData() / "mr-chest-dicom-seg3d")) {
    if (e.path().filename() != "README.txt") slices.push_back(e.path());
  }
  std::sort(slices.begin(), slices.end());
  ASSERT_GT(slices.size(), 4u);
  for (const fs::path& f : slices) fs::copy_file(f, dup / f.filename());
  fs::copy_file(slices[3], dup / "copy-of-slice.dcm");  // two slices at one position
  ServerProcess server(scratch.path(), {"--data-root", (scratch / "roots").string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  try {
    client.LoadVolume("dup");
    FAIL() << "a folder with a duplicate slice loaded";
  } catch (const RpcError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("same position"), std::string::npos) << message;
    EXPECT_NE(message.find("'dup/copy-of-slice.dcm'"), std::string::npos) << message;
    EXPECT_EQ(message.find("'/"), std::string::npos) << "a quote closes before the file name: " << message;
  }
}

}  // namespace
}  // namespace cinevol::testing
