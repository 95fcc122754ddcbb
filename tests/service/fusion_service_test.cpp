// A second volume fused with a session's on a real cinevol-server (issue
// 59): named by the scene at creation, drawn in frames, over slices and in
// picks; changed and removed by the fusion event; what cannot be fused
// refused by name, the session as it was.
#include <gtest/gtest.h>

#include "encode/image_codecs.h"
#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"
#include "support/time_series_nifti.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

// The head phantom (48 mm) and a sphere on a coarser grid over the same
// box, both centred on the patient's origin; neither names a Frame of
// Reference, so fusing them needs align_by_patient.
constexpr const char* kHead = "phantom:head?size=48";
constexpr const char* kSphere = "phantom:sphere?size=24&spacing=2";

v1::Fusion SphereFusion(bool align = true) {
  v1::Fusion fusion;
  fusion.set_volume_id(kSphere);
  fusion.set_align_by_patient(align);
  fusion.mutable_overlay()->set_window(1000);
  fusion.mutable_overlay()->set_level(500);
  fusion.mutable_overlay()->set_opacity(1);
  return fusion;
}

v1::CreateSessionRequest FusedSession(const v1::Fusion& fusion) {
  v1::CreateSessionRequest request = SmallSession("ct-bone", 64, 48);
  request.mutable_scene()->mutable_transfer_function()->set_preset("ct-bone");
  *request.mutable_scene()->mutable_fusion() = fusion;
  return request;
}

// The centre pixel of the axial slice through the patient's origin.
std::array<int, 3> CentrePixel(Client& client, const std::string& session) {
  v1::SliceRequest axial;
  axial.set_session_id(session);
  axial.set_axis(v1::AXIAL);
  axial.set_position_mm(0);
  axial.set_window(2000);
  axial.set_level(0);
  const v1::SliceImage slice = client.RenderSlice(axial);
  const ImageRgb8 png = DecodePng(std::vector<std::uint8_t>(slice.png().begin(), slice.png().end()));
  const std::uint8_t* p = &png.bytes[3 * (std::size_t(png.height / 2) * png.width + png.width / 2)];
  return {p[0], p[1], p[2]};
}

v1::SessionEvent FusionEvent(std::uint64_t seq, const v1::Fusion& fusion) {
  v1::SessionEvent event;
  event.set_seq(seq);
  *event.mutable_fusion() = fusion;
  return event;
}

TEST(FusionSession, ASecondVolumeShowsInFramesSlicesAndPicksAndTheEventChangesIt) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--volume", kHead, "--volume", kSphere});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(FusedSession(SphereFusion()));
  EXPECT_EQ(created.scene().fusion().volume_id(), kSphere);
  EXPECT_EQ(created.scene().fusion().overlay().color_map(), v1::HOT) << "the default colour map";

  // The sphere's 1000 is the top of the overlay's window: white through the hot map.
  EXPECT_EQ(CentrePixel(client, created.session_id()), (std::array<int, 3>{255, 255, 255}));
  v1::PickRequest at;
  at.set_session_id(created.session_id());
  at.set_x(32);
  at.set_y(24);
  const v1::PickResult hit = client.Pick(at);
  ASSERT_TRUE(hit.hit());
  ASSERT_TRUE(hit.has_fused_value());
  EXPECT_GT(hit.fused_value(), 0) << "the pick is inside the sphere or on its edge";

  auto stream = client.Attach(created.session_id());
  EXPECT_TRUE(WaitFrame(
      *stream, [](const v1::Frame&) { return true; }, 60s))
      << "a frame of the fused scene";

  // The event changes how it shows (a grey map), then removes it.
  v1::Fusion grey = SphereFusion();
  grey.mutable_overlay()->set_color_map(v1::GRAY);
  grey.mutable_overlay()->set_level(1000);
  const v1::SessionState changed = client.SendEvents(created.session_id(), {FusionEvent(1, grey)});
  EXPECT_EQ(changed.scene().fusion().overlay().color_map(), v1::GRAY);
  const std::array<int, 3> mid = CentrePixel(client, created.session_id());
  EXPECT_NEAR(mid[0], 128, 1) << "1000 is the middle of a window on 1000";
  EXPECT_EQ(mid[0], mid[2]);
  const v1::SessionState removed = client.SendEvents(created.session_id(), {FusionEvent(2, v1::Fusion{})});
  EXPECT_FALSE(removed.scene().has_fusion());
  const std::array<int, 3> plain = CentrePixel(client, created.session_id());
  EXPECT_EQ(plain[0], plain[2]) << "grey: no overlay";
  EXPECT_FALSE(client.Pick(at).has_fused_value());
  EXPECT_TRUE(WaitFrame(
      *stream, [](const v1::Frame& f) { return f.last_event_seq() >= 2; }, 60s));
}

TEST(FusionSession, WhatCannotBeFusedIsRefusedByName) {
  ScratchDir scratch;
  WriteMovingSphere(scratch / "beat.nii", {});
  ServerProcess server(scratch.path(),
                       {"--volume", kHead, "--volume", kSphere, "--volume", (scratch / "beat.nii").string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  ExpectRpcError([&] { client.CreateSession(FusedSession(SphereFusion(false))); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "set align_by_patient");
  v1::Fusion nowhere = SphereFusion();
  nowhere.set_volume_id("no-such-volume");
  ExpectRpcError([&] { client.CreateSession(FusedSession(nowhere)); }, grpc::StatusCode::NOT_FOUND, "no-such-volume");
  v1::Fusion series = SphereFusion();
  series.set_volume_id("beat");
  ExpectRpcError([&] { client.CreateSession(FusedSession(series)); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "a time series of 5 phases");
  v1::Fusion suv = SphereFusion();
  suv.set_suv(true);
  ExpectRpcError([&] { client.CreateSession(FusedSession(suv)); }, grpc::StatusCode::INVALID_ARGUMENT, "has no SUVbw");
  v1::Fusion bad_window = SphereFusion();
  bad_window.mutable_overlay()->set_window(-1);
  ExpectRpcError([&] { client.CreateSession(FusedSession(bad_window)); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "fusion.overlay.window");

  // A session fuses only the volume it began with; a refused event leaves it as it was.
  const auto created = client.CreateSession(FusedSession(SphereFusion()));
  v1::Fusion other = SphereFusion();
  other.set_volume_id(kHead);
  ExpectRpcError([&] { client.SendEvents(created.session_id(), {FusionEvent(1, other)}); },
                 grpc::StatusCode::INVALID_ARGUMENT, "is not this session's second volume");
  v1::Fusion opaque = SphereFusion();
  opaque.mutable_overlay()->set_opacity(2);
  ExpectRpcError([&] { client.SendEvents(created.session_id(), {FusionEvent(2, opaque)}); },
                 grpc::StatusCode::INVALID_ARGUMENT, "fusion.overlay.opacity");
  const v1::SessionState state = client.SendEvents(created.session_id(), {});
  EXPECT_EQ(state.scene().fusion().volume_id(), kSphere);
  EXPECT_EQ(state.scene().fusion().overlay().opacity(), 1.0f);
  const auto plain = client.CreateSession(SmallSession());
  ExpectRpcError([&] { client.SendEvents(plain.session_id(), {FusionEvent(1, SphereFusion())}); },
                 grpc::StatusCode::INVALID_ARGUMENT, "(none)");
}

}  // namespace
}  // namespace cinevol::testing
