// The render service end to end on the CPU backend: a real cinevol-server on
// loopback, real gRPC, frames that follow camera, transfer-function and light
// edits, snapshots, two sessions apart, idle refinement that stops.
#include <cmath>
#include <cstdlib>
#include <gtest/gtest.h>

#include <thread>

#include "encode/hdr_images.h"
#include "image_metrics.h"
#include "pipeline/frame_cost.h"
#include "server_process.h"
#include "service_test_support.h"
#include "support/gpu.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

v1::SessionEvent CameraView(v1::NamedView view) {
  v1::SessionEvent e;
  e.mutable_camera()->set_view(view);
  return e;
}

// Every frame up to and including the final one, 30 s at most for each.
std::vector<v1::Frame> FramesUntilFinal(SessionStream& stream) {
  std::vector<v1::Frame> frames;
  while (auto f = WaitFrame(stream, [](const v1::Frame&) { return true; }, 30s)) {
    frames.push_back(*f);
    if (f->final()) break;
  }
  return frames;
}

TEST(SessionStream, FramesFollowCameraTransferFunctionAndLightEdits) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession());
  auto stream = client.Attach(created.session_id());

  const auto base = WaitFinal(*stream);
  ASSERT_TRUE(base) << stream->status().error_message();
  EXPECT_EQ(base->width(), 96u);
  EXPECT_EQ(base->height(), 64u);
  EXPECT_GE(base->accumulated_spp(), 16u);
  EXPECT_EQ(base->last_event_seq(), 0u);
  const ImageRgb8 before = Decode(*base);
  EXPECT_GT(MeanLevel(before), 1.0) << "the phantom's bone should show";

  // A camera move: another view of the head.
  const std::uint64_t camera_seq = stream->Send(CameraView(v1::LEFT));
  const auto moved = WaitFinal(*stream, camera_seq);
  ASSERT_TRUE(moved);
  EXPECT_EQ(moved->last_event_seq(), camera_seq);
  EXPECT_GT(moved->frame_id(), base->frame_id());
  EXPECT_GT(MeanAbsDiff(before, Decode(*moved)), 2.0);

  // A transfer-function edit: muscle under the skin instead of bone. (Two
  // finals of one state differ by 0.9-1.9 on average at 16 spp; this edit
  // moves the image by about 5, soft tissue by only about 2.)
  v1::SessionEvent tf;
  tf.mutable_transfer_function()->set_preset("ct-muscle");
  const std::uint64_t tf_seq = stream->Send(tf);
  const auto muscle = WaitFinal(*stream, tf_seq);
  ASSERT_TRUE(muscle);
  EXPECT_GT(MeanAbsDiff(Decode(*moved), Decode(*muscle)), 3.0);

  // A light edit: only the sky is left, at a quarter of its intensity, so
  // the image darkens.
  v1::SessionEvent lights;
  for (const v1::Light& l : created.scene().lights()) {
    if (!l.has_environment()) continue;
    v1::Light* sky = lights.mutable_lights()->add_lights();
    *sky = l;
    sky->mutable_environment()->set_intensity(0.25f * l.environment().intensity());
  }
  const std::uint64_t light_seq = stream->Send(lights);
  const auto dim = WaitFinal(*stream, light_seq);
  ASSERT_TRUE(dim);
  EXPECT_LT(MeanLevel(Decode(*dim)), MeanLevel(Decode(*muscle)) - 10.0);
  EXPECT_GT(light_seq, tf_seq);

  // Stills of the current state, as PNG and EXR.
  v1::SnapshotRequest still;
  still.set_session_id(created.session_id());
  still.set_spp(8);
  const auto png = client.Snapshot(still);
  EXPECT_EQ(png.format(), v1::PNG);
  EXPECT_EQ(png.width(), 96u);
  EXPECT_EQ(png.spp(), 8u);
  WriteFile(scratch / "still.png", {png.image().begin(), png.image().end()});
  const ImageRgb8 still_image = ReadPng(scratch / "still.png");
  EXPECT_EQ(still_image.width, 96);
  EXPECT_LT(MeanAbsDiff(still_image, Decode(*dim)), 20.0) << "the still shows the session's current state";
  still.set_format(v1::EXR);
  const auto exr = client.Snapshot(still);
  WriteFile(scratch / "still.exr", {exr.image().begin(), exr.image().end()});
  EXPECT_EQ(ReadExr(scratch / "still.exr").height, 64);

  client.CloseSession(created.session_id());
  EXPECT_TRUE(stream->Finish(10s).ok());
  EXPECT_FALSE(FindSessionStatus(client, created.session_id()));
}

TEST(SessionStream, TwoSessionsSeeOnlyTheirOwnState) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto a = client.CreateSession(SmallSession("ct-bone"));
  const auto b = client.CreateSession(SmallSession("ct-muscle"));
  ASSERT_NE(a.session_id(), b.session_id());
  auto stream_a = client.Attach(a.session_id());
  auto stream_b = client.Attach(b.session_id());
  const auto a0 = WaitFinal(*stream_a);
  const auto b0 = WaitFinal(*stream_b);
  ASSERT_TRUE(a0 && b0);
  // About 5 apart; two finals of one state differ by 1-2 at 16 spp.
  EXPECT_GT(MeanAbsDiff(Decode(*a0), Decode(*b0)), 3.0) << "different transfer functions";

  const std::uint64_t seq = stream_a->Send(CameraView(v1::SUPERIOR));
  ASSERT_TRUE(WaitFinal(*stream_a, seq));
  // B is refined and idle: A's edit renders nothing for it.
  EXPECT_FALSE(stream_b->Next(1s)) << "B received a frame after A's edit";
  const auto status_b = FindSessionStatus(client, b.session_id());
  ASSERT_TRUE(status_b);
  EXPECT_EQ(status_b->last_event_seq(), 0u);
  EXPECT_EQ(status_b->state(), v1::SessionStatus::IDLE);
}

TEST(SessionStream, IdleRefinementReachesTheTargetThenStops) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  v1::CreateSessionRequest request = SmallSession("ct-bone", 96, 64, 32);
  request.mutable_stream()->set_jpeg_quality(40);
  request.mutable_stream()->set_final_jpeg_quality(98);
  request.mutable_stream()->set_error_target(0);  // to the cap
  const auto created = client.CreateSession(request);
  auto stream = client.Attach(created.session_id());

  const std::vector<v1::Frame> frames = FramesUntilFinal(*stream);
  ASSERT_FALSE(frames.empty());
  const v1::Frame& last = frames.back();
  ASSERT_TRUE(last.final());
  EXPECT_GE(last.accumulated_spp(), 32u);
  for (std::size_t i = 1; i < frames.size(); ++i) {
    EXPECT_GT(frames[i].accumulated_spp(), frames[i - 1].accumulated_spp()) << "samples accumulate";
  }
  // The final frame is encoded at the higher quality: larger than its predecessor.
  ASSERT_GE(frames.size(), 2u);
  EXPECT_GT(last.jpeg().size(), frames[frames.size() - 2].jpeg().size());

  // Then nothing: no frames, and the server's CPU goes idle.
  EXPECT_FALSE(stream->Next(1s));
  const double cpu_before = server.CpuSeconds();
  std::this_thread::sleep_for(1s);
  EXPECT_LT(server.CpuSeconds() - cpu_before, 0.1) << "the server kept working after refinement ended";
  const auto status = FindSessionStatus(client, created.session_id());
  ASSERT_TRUE(status);
  EXPECT_EQ(status->state(), v1::SessionStatus::IDLE);
  EXPECT_EQ(status->frames_rendered(), frames.size());
}

// A client that sends its camera again (a pointer move of no pixel) changes
// nothing: the answer goes on from the samples the view holds, at full size.
TEST(SessionStream, ACameraSentAgainKeepsTheSamples) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession());
  auto stream = client.Attach(created.session_id());
  const auto base = WaitFinal(*stream);
  ASSERT_TRUE(base) << stream->status().error_message();

  v1::SessionEvent same;
  *same.mutable_camera() = created.scene().camera();
  const std::uint64_t seq = stream->Send(same);
  const auto answer = WaitFrame(*stream, [seq](const v1::Frame& f) { return f.last_event_seq() >= seq; });
  ASSERT_TRUE(answer) << stream->status().error_message();
  EXPECT_GT(answer->accumulated_spp(), base->accumulated_spp()) << "the samples started over";
  EXPECT_EQ(answer->width(), base->width());
  EXPECT_TRUE(answer->final());

  // A camera that does move still starts over.
  v1::SessionEvent moved = same;
  moved.mutable_camera()->mutable_eye()->set_x(moved.camera().eye().x() + 10);
  const std::uint64_t moved_seq = stream->Send(moved);
  const auto restarted = WaitFrame(*stream, [moved_seq](const v1::Frame& f) { return f.last_event_seq() >= moved_seq; });
  ASSERT_TRUE(restarted);
  EXPECT_LT(restarted->accumulated_spp(), base->accumulated_spp());
}

// A clipping event cuts the phantom: a plane keeping only what lies beyond
// the volume leaves the background, and clearing it brings the head back.
TEST(SessionStream, AClippingEventCutsAndClearingItRestores) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession());
  auto stream = client.Attach(created.session_id());
  const auto whole = WaitFinal(*stream);
  ASSERT_TRUE(whole);
  v1::SessionEvent cut;
  v1::ClipPlane* plane = cut.mutable_clipping()->add_planes();
  plane->mutable_point()->set_x(1e5f);  // far to the patient's left of any voxel
  plane->mutable_normal()->set_x(1);
  const auto empty = WaitFinal(*stream, stream->Send(cut));
  ASSERT_TRUE(empty);
  v1::SessionEvent clear;
  clear.mutable_clipping();
  const auto back = WaitFinal(*stream, stream->Send(clear));
  ASSERT_TRUE(back);
  const RgbImage a = DecodeFrame(*whole), b = DecodeFrame(*empty), c = DecodeFrame(*back);
  const auto psnr = [](const RgbImage& x, const RgbImage& y) {
    return Psnr(ImageRgb8{x.width, x.height, x.rgb}, ImageRgb8{y.width, y.height, y.rgb});
  };
  // The share of pixels that differ between two images by more than noise does.
  const auto share_unlike = [](const RgbImage& x, const RgbImage& y) {
    size_t unlike = 0;
    for (size_t i = 0; i < x.rgb.size(); i += 3)
      for (int k = 0; k < 3; ++k)
        if (std::abs(int(x.rgb[i + k]) - int(y.rgb[i + k])) > 24) {
          ++unlike;
          break;
        }
    return double(unlike) / double(x.rgb.size() / 3);
  };
  // The head covers about 14% of this frame. (A PSNR bound against the whole
  // image sat too close to what it measured, 19.7 dB, under a loaded suite.)
  EXPECT_GT(share_unlike(a, b), 0.07) << "the cut image still shows the head";
  EXPECT_GT(psnr(a, c), 30.0) << "clearing the clipping brings the head back";
}

// A client that asks for a lossless final frame gets it as PNG, the frames
// before it as JPEG; a settings event switches back.
TEST(SessionStream, TheFinalFrameComesAsPngWhereAsked) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  v1::CreateSessionRequest request = SmallSession("ct-bone", 96, 64, 16);
  request.mutable_stream()->set_error_target(0);  // to the cap
  request.mutable_stream()->set_final_format(v1::FINAL_FORMAT_PNG);
  const auto created = client.CreateSession(request);
  auto stream = client.Attach(created.session_id());
  const std::vector<v1::Frame> frames = FramesUntilFinal(*stream);
  ASSERT_GE(frames.size(), 2u);
  const v1::Frame& last = frames.back();
  ASSERT_TRUE(last.final());
  ASSERT_TRUE(last.has_png());
  EXPECT_EQ(last.png().compare(0, 8, "\x89PNG\r\n\x1a\n"), 0);
  const RgbImage png = DecodeFrame(last);
  EXPECT_EQ(png.width, 96);
  EXPECT_EQ(png.height, 64);
  EXPECT_EQ(last.width(), 96u);
  const v1::Frame& before = frames[frames.size() - 2];
  ASSERT_TRUE(before.has_jpeg());
  // One more frame of samples than the JPEG before it: the same image, near enough.
  const RgbImage jpeg = DecodeFrame(before);
  EXPECT_GT(Psnr(ImageRgb8{png.width, png.height, png.rgb}, ImageRgb8{jpeg.width, jpeg.height, jpeg.rgb}), 30.0);

  v1::SessionEvent back, move;
  back.mutable_stream()->set_final_format(v1::FINAL_FORMAT_JPEG);
  stream->Send(back);
  move.mutable_camera()->CopyFrom(created.scene().camera());
  move.mutable_camera()->mutable_eye()->set_x(move.camera().eye().x() + 10);
  const auto again = WaitFinal(*stream, stream->Send(move));
  ASSERT_TRUE(again);
  EXPECT_TRUE(again->has_jpeg());
}

// An easy error target ends refinement long before a cap it would never
// reach in the test's time; the final frame carries the estimate it met, and
// the session is idle afterwards.
TEST(SessionStream, RefinementEndsAtTheErrorTarget) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  v1::CreateSessionRequest request = SmallSession();
  request.mutable_stream()->set_target_spp(65536);
  request.mutable_stream()->set_error_target(0.05f);
  const auto created = client.CreateSession(request);
  auto stream = client.Attach(created.session_id());
  const auto last = WaitFinal(*stream);
  ASSERT_TRUE(last) << stream->status().error_message();
  EXPECT_LT(last->accumulated_spp(), 65536u);
  EXPECT_GT(last->estimated_error(), 0.0f);
  EXPECT_LE(last->estimated_error(), 0.05f);
  EXPECT_FALSE(stream->Next(1s)) << "a frame after the final one";
  const auto status = FindSessionStatus(client, created.session_id());
  ASSERT_TRUE(status);
  EXPECT_EQ(status->state(), v1::SessionStatus::IDLE);
}

TEST(SessionStream, AMovingViewStreamsSmallerFramesThenRefinesAtFullSize) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  v1::CreateSessionRequest request = SmallSession();
  request.mutable_stream()->set_interactive_frame_ms(0.001f);  // no frame meets it: the smallest scale
  const auto created = client.CreateSession(request);
  auto stream = client.Attach(created.session_id());
  const auto still = WaitFinal(*stream);
  ASSERT_TRUE(still) << stream->status().error_message();
  EXPECT_EQ(still->resolution_scale(), 1.0f);

  // A camera move: the CPU picks the moving frame's size from the costs it
  // measured while still, so a budget nothing meets takes the smallest size
  // (an eighth, pipeline/frame_cost.h) at once.
  v1::SessionEvent zoom;
  zoom.mutable_camera()->set_view(v1::ANTERIOR);
  zoom.mutable_camera()->set_fov_y_deg(25.0f);
  const std::uint64_t seq = stream->Send(zoom);
  const auto moving = WaitFrame(*stream, [seq](const v1::Frame& f) { return f.last_event_seq() >= seq; });
  ASSERT_TRUE(moving) << stream->status().error_message();
  EXPECT_EQ(moving->resolution_scale(), kCpuInteractiveScales[std::size(kCpuInteractiveScales) - 1]);
  EXPECT_FALSE(moving->final());
  const ImageRgb8 small = Decode(*moving);
  EXPECT_EQ(small.width, 96) << "upsampled to the viewport";
  EXPECT_EQ(small.height, 64);
  EXPECT_EQ(moving->width(), 96u);

  const auto refined = WaitFinal(*stream, seq);
  ASSERT_TRUE(refined);
  EXPECT_EQ(refined->resolution_scale(), 1.0f);
  EXPECT_GE(refined->accumulated_spp(), 16u);

  // A client that stretches frames itself gets them at the size they rendered.
  v1::SessionEvent stretch;
  stretch.mutable_stream()->set_frames_at_rendered_size(true);
  stream->Send(stretch);
  zoom.mutable_camera()->set_fov_y_deg(30.0f);
  const std::uint64_t seq2 = stream->Send(zoom);
  const auto rendered = WaitFrame(*stream, [seq2](const v1::Frame& f) { return f.last_event_seq() >= seq2; });
  ASSERT_TRUE(rendered) << stream->status().error_message();
  ASSERT_LT(rendered->resolution_scale(), 1.0f);
  const ImageRgb8 own = Decode(*rendered);
  EXPECT_EQ(own.width, std::lround(96 * rendered->resolution_scale())) << "the size it rendered";
  EXPECT_EQ(own.height, std::lround(64 * rendered->resolution_scale()));
  EXPECT_EQ(rendered->width(), 96u) << "to be shown at the viewport";
  EXPECT_EQ(rendered->height(), 64u);
  const auto full = WaitFinal(*stream, seq2);
  ASSERT_TRUE(full);
  EXPECT_EQ(Decode(*full).width, 96) << "a still view refines at full size";
}

TEST(SessionStream, PauseStopsFramesAndResumeBringsThemBack) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession("ct-bone", 96, 64, 4096));
  auto stream = client.Attach(created.session_id());
  ASSERT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }));
  v1::SessionEvent pause;
  pause.mutable_pause();
  stream->Send(pause);
  ASSERT_TRUE(Eventually([&] { return FindSessionStatus(client, created.session_id())->state() ==
                                      v1::SessionStatus::PAUSED; }, 5s));
  std::this_thread::sleep_for(300ms);  // frames already encoding may still arrive
  while (stream->Next(0ms)) {
  }
  EXPECT_FALSE(stream->Next(1s)) << "frames arrived while paused";
  v1::SessionEvent resume;
  resume.mutable_resume();
  const std::uint64_t seq = stream->Send(resume);
  EXPECT_TRUE(WaitFrame(*stream, [seq](const v1::Frame& f) { return f.last_event_seq() >= seq; }, 30s));
}

// A preset that does not fit the volume is said once a session, as a
// warning on the stream: an MR preset on the CT phantom at the start, the
// angiography preset (no contrast in the phantom) when an edit picks it;
// picking either again says nothing more.
TEST(SessionStream, APresetThatDoesNotFitTheVolumeIsSaidOnce) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession("mr-t2-brain", 64, 48, 4));
  auto stream = client.Attach(created.session_id());
  std::vector<std::string> warnings;
  auto read_until_final = [&](std::uint64_t seq) {
    const auto end = std::chrono::steady_clock::now() + 60s;
    while (std::chrono::steady_clock::now() < end) {
      const auto m = stream->Next(200ms);
      if (m && m->has_notice() && m->notice().level() == v1::Notice::WARNING) warnings.push_back(m->notice().message());
      if (m && m->has_frame() && m->frame().final() && m->frame().last_event_seq() >= seq) return true;
    }
    return false;
  };
  ASSERT_TRUE(read_until_final(0));
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("preset 'mr-t2-brain' is for MR"), std::string::npos) << warnings[0];
  for (const char* preset : {"ct-vessels", "mr-t2-brain", "ct-vessels", "ct-bone"}) {
    v1::SessionEvent edit;
    edit.mutable_transfer_function()->set_preset(preset);
    ASSERT_TRUE(read_until_final(stream->Send(edit))) << preset;
  }
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_NE(warnings[1].find("preset 'ct-vessels' shows contrast-filled vessels"), std::string::npos) << warnings[1];
}

TEST(SessionStream, ASecondAttachTakesTheSessionOver) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession());
  auto first = client.Attach(created.session_id());
  ASSERT_TRUE(WaitFrame(*first, [](const v1::Frame&) { return true; }));
  auto second = client.Attach(created.session_id());
  const auto resumed = WaitFinal(*second);
  ASSERT_TRUE(resumed) << "the new stream gets the session's frames";
  EXPECT_TRUE(Eventually([&] { return first->ended(); }, 10s));
  EXPECT_EQ(first->status().error_code(), grpc::StatusCode::ABORTED);
}

TEST(SessionStream, StreamsFromTheCudaBackend) {
  CINEVOL_REQUIRE_CUDA();
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {}, "cuda");
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession("ct-bone", 320, 240, 64));
  EXPECT_NE(created.device().find("cuda:"), std::string::npos) << created.device();
  auto stream = client.Attach(created.session_id());
  const auto base = WaitFinal(*stream);
  ASSERT_TRUE(base) << stream->status().error_message();
  EXPECT_GT(MeanLevel(Decode(*base)), 1.0);
  const std::uint64_t seq = stream->Send(CameraView(v1::LEFT));
  const auto moved = WaitFinal(*stream, seq);
  ASSERT_TRUE(moved);
  EXPECT_GT(MeanAbsDiff(Decode(*base), Decode(*moved)), 2.0);
  EXPECT_TRUE(FindSessionStatus(client, created.session_id())->holds_device_memory());
  const v1::ServerStatus status = client.Status();
  ASSERT_GE(status.devices_size(), 1);
  EXPECT_GT(status.devices(0).memory_total_bytes(), 0u);
  client.CloseSession(created.session_id());
}

}  // namespace
}  // namespace cinevol::testing
