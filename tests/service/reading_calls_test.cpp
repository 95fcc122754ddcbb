// RenderSlice and Pick on a session (docs/reading.md): a real cinevol-server
// on loopback, the raw stubs, every call under a deadline.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "encode/image_codecs.h"
#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

grpc::Status Slice(v1::SessionService::Stub& stub, const v1::SliceRequest& request, v1::SliceImage* out,
                   const std::string& token = {}) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 30s);
  if (!token.empty()) context.AddMetadata("authorization", "Bearer " + token);
  return stub.RenderSlice(&context, request, out);
}

grpc::Status Pick(v1::SessionService::Stub& stub, const v1::PickRequest& request, v1::PickResult* out,
                  const std::string& token = {}) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 30s);
  if (!token.empty()) context.AddMetadata("authorization", "Bearer " + token);
  return stub.Pick(&context, request, out);
}

std::vector<std::string> Letters(const v1::SliceImage& image) {
  return {image.edge_letters().begin(), image.edge_letters().end()};
}

TEST(ReadingCalls, SlicesOfTheSessionsVolumeAtItsOwnSpacingWithTheirLetters) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession());  // phantom:head?size=48, CT in HU
  auto stub = v1::SessionService::NewStub(client.channel());

  v1::SliceRequest request;
  request.set_session_id(created.session_id());
  request.set_axis(v1::AXIAL);
  v1::SliceImage axial;
  const grpc::Status status = Slice(*stub, request, &axial);
  ASSERT_TRUE(status.ok()) << status.error_message();
  const ImageRgb8 png = DecodePng(std::vector<std::uint8_t>(axial.png().begin(), axial.png().end()));
  EXPECT_EQ(png.width, 48);
  EXPECT_EQ(png.height, 48);
  EXPECT_EQ(axial.width(), 48u);
  EXPECT_EQ(Letters(axial), (std::vector<std::string>{"R", "L", "A", "P"}));
  EXPECT_FLOAT_EQ(axial.window(), 350) << "CT in HU: soft tissue by default";
  EXPECT_FLOAT_EQ(axial.level(), 50);

  request.set_axis(v1::SAGITTAL);
  request.set_window_preset("bone");
  v1::SliceImage sagittal;
  ASSERT_TRUE(Slice(*stub, request, &sagittal).ok());
  EXPECT_EQ(Letters(sagittal), (std::vector<std::string>{"A", "P", "S", "I"}));
  EXPECT_FLOAT_EQ(sagittal.window(), 1000);

  request.set_window_preset("soup");
  EXPECT_EQ(Slice(*stub, request, &sagittal).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  request.clear_window_preset();
  request.set_window(0.5f);
  request.set_level(40);
  const grpc::Status narrow = Slice(*stub, request, &sagittal);
  EXPECT_EQ(narrow.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(narrow.error_message().find("window"), std::string::npos) << narrow.error_message();
}

TEST(ReadingCalls, APickAtTheViewsCentreFindsTheHeadAndOnlyItsOwnerMayAsk) {
  ScratchDir scratch;
  std::ofstream(scratch / "tokens") << "alice-token alice\nbob-token bob\n";
  ServerProcess server(scratch.path(), {"--auth-tokens", (scratch / "tokens").string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Client alice = server.Connect("alice-token");
  const auto created = alice.CreateSession(SmallSession());
  auto stub = v1::SessionService::NewStub(alice.channel());

  v1::PickRequest request;
  request.set_session_id(created.session_id());
  request.set_x(48);
  request.set_y(32);
  v1::PickResult hit;
  const grpc::Status status = Pick(*stub, request, &hit, "alice-token");
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_TRUE(hit.hit());
  EXPECT_GT(hit.value(), 100) << "ct-bone stops on bone, far above water's 0 HU";
  EXPECT_TRUE(std::isfinite(hit.position_mm().x()) && std::isfinite(hit.position_mm().z()));

  // The same point of a frame shown at twice the size (a resize on its way): the same ray.
  v1::PickRequest shown = request;
  shown.set_x(96);
  shown.set_y(64);
  shown.mutable_frame()->set_width(192);
  shown.mutable_frame()->set_height(128);
  v1::PickResult same;
  ASSERT_TRUE(Pick(*stub, shown, &same, "alice-token").ok());
  EXPECT_NEAR(same.position_mm().y(), hit.position_mm().y(), 1.0);
  shown.mutable_frame()->set_width(0);
  EXPECT_EQ(Pick(*stub, shown, &same, "alice-token").error_code(), grpc::StatusCode::INVALID_ARGUMENT);

  EXPECT_EQ(Pick(*stub, request, &hit, "bob-token").error_code(), grpc::StatusCode::PERMISSION_DENIED);
  request.set_x(-3);
  EXPECT_EQ(Pick(*stub, request, &hit, "alice-token").error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  request.set_x(0.5f);
  request.set_threshold(1.5f);
  EXPECT_EQ(Pick(*stub, request, &hit, "alice-token").error_code(), grpc::StatusCode::INVALID_ARGUMENT);
}

}  // namespace
}  // namespace cinevol::testing
