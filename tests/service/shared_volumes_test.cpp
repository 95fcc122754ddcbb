// Sessions on one volume share its copy on the device, and the server's
// status says so: one copy, rendered by both; none once both are closed.
// The copy is made as a session is created, before its first frame.
#include <gtest/gtest.h>

#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

const v1::VolumeInfo* FindVolume(const v1::ServerStatus& status, const std::string& id) {
  for (const v1::VolumeInfo& v : status.volumes()) {
    if (v.id() == id) return &v;
  }
  return nullptr;
}

TEST(SharedVolumes, TwoSessionsOnOneVolumeHoldOneCopy) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const v1::CreateSessionRequest request = SmallSession();
  const auto a = client.CreateSession(request), b = client.CreateSession(request);
  auto stream_a = client.Attach(a.session_id()), stream_b = client.Attach(b.session_id());
  // A final frame from each: both pipelines hold the volume (until their stream goes).
  ASSERT_TRUE(WaitFinal(*stream_a)) << stream_a->status().error_message();
  ASSERT_TRUE(WaitFinal(*stream_b)) << stream_b->status().error_message();

  v1::ServerStatus status = client.Status();
  ASSERT_EQ(status.devices_size(), 1);
  EXPECT_EQ(status.devices(0).volume_copies(), 1u);
  EXPECT_GT(status.devices(0).volume_copy_bytes(), 0u);
  const v1::VolumeInfo* volume = FindVolume(status, request.volume_id());
  ASSERT_NE(volume, nullptr);
  ASSERT_EQ(volume->copies_size(), 1);
  EXPECT_EQ(volume->copies(0).device(), "cpu");
  EXPECT_EQ(volume->copies(0).renderers(), 2u);
  EXPECT_EQ(volume->copies(0).bytes(), status.devices(0).volume_copy_bytes());

  const auto [code, output] = RunProgram(CliPath(), {"status", "--server", server.address()}, scratch / "cli.log");
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find("\nVOLUME "), std::string::npos) << output;
  EXPECT_NE(output.find(request.volume_id() + " "), std::string::npos) << output;

  client.CloseSession(a.session_id());
  client.CloseSession(b.session_id());
  // The sessions' workers free their pipelines on their next step.
  EXPECT_TRUE(Eventually([&] { return client.Status().devices(0).volume_copies() == 0; }, 30s))
      << "the last session's end frees the copy";
  status = client.Status();
  EXPECT_EQ(status.devices(0).volume_copy_bytes(), 0u);
  volume = FindVolume(status, request.volume_id());
  ASSERT_NE(volume, nullptr);
  EXPECT_EQ(volume->copies_size(), 0);
}

// CreateSession prepares the volume on the session's device, on the setup
// pool: the first frame does not, on a worker other sessions share.
TEST(SharedVolumes, ANewSessionFindsItsVolumePreparedBeforeItsFirstFrame) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const v1::CreateSessionRequest request = SmallSession();
  const auto created = client.CreateSession(request);  // never attached: no frame renders
  const v1::ServerStatus status = client.Status();
  const v1::VolumeInfo* volume = FindVolume(status, request.volume_id());
  ASSERT_NE(volume, nullptr);
  ASSERT_EQ(volume->copies_size(), 1) << "the copy exists as the creation answers";
  EXPECT_EQ(volume->copies(0).device(), "cpu");
  EXPECT_EQ(volume->copies(0).renderers(), 1u);
  client.CloseSession(created.session_id());
  EXPECT_TRUE(Eventually([&] { return client.Status().devices(0).volume_copies() == 0; }, 30s))
      << "a session that never rendered frees the copy too";
}

}  // namespace
}  // namespace cinevol::testing
