// A time series on a real cinevol-server (issue 59): its phases and times in
// VolumeInfo; a session's phase set by an event, shown by frames, slices and
// picks; playing steps the frames through the phases and loops; what does
// not fit the series refused by name.
#include <gtest/gtest.h>

#include <set>

#include "encode/image_codecs.h"
#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"
#include "runtime/volume_registry.h"
#include "support/time_series_nifti.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

v1::SessionEvent TimeEvent(std::uint64_t seq, int phase, bool playing = false, float rate = 0) {
  v1::SessionEvent event;
  event.set_seq(seq);
  event.mutable_time()->set_phase(std::uint32_t(phase));
  event.mutable_time()->set_playing(playing);
  event.mutable_time()->set_phases_per_second(rate);
  return event;
}

// The mean column of the bright pixels of an axial slice through the sphere's centre (its 13th slice).
double SphereColumn(Client& client, const std::string& session, const v1::VolumeInfo& volume) {
  v1::SliceRequest axial;
  axial.set_session_id(session);
  axial.set_axis(v1::AXIAL);
  axial.set_position_mm(volume.origin_mm().z() + volume.direction(8) * 12);
  axial.set_window(1);
  axial.set_level(500);
  const v1::SliceImage slice = client.RenderSlice(axial);
  const ImageRgb8 png = DecodePng(std::vector<std::uint8_t>(slice.png().begin(), slice.png().end()));
  double sum = 0, count = 0;
  for (int y = 0; y < png.height; ++y) {
    for (int x = 0; x < png.width; ++x) {
      if (png.bytes[3 * (std::size_t(y) * png.width + x)] > 128) sum += x, ++count;
    }
  }
  return count > 0 ? sum / count : -1;
}

TEST(TimeSeriesSession, APhaseEventShowsThatPhaseInFramesSlicesAndPicks) {
  ScratchDir scratch;
  WriteMovingSphere(scratch / "sphere.nii", {});
  ServerProcess server(scratch.path(), {"--data-root", scratch.path().string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const v1::VolumeInfo volume = client.LoadVolume("sphere.nii");
  EXPECT_EQ(volume.phases(), 5u);
  ASSERT_EQ(volume.phase_seconds_size(), 5);
  EXPECT_NEAR(volume.phase_seconds(4), 0.4, 1e-6);
  EXPECT_GE(volume.memory_bytes(), 5u * 24 * 24 * 24 * 2) << "every phase counted";

  v1::CreateSessionRequest request = SmallSession("ct-bone", 64, 48);
  request.set_volume_id(volume.id());
  const auto created = client.CreateSession(request);
  const double first = SphereColumn(client, created.session_id(), volume);
  const v1::SessionState after = client.SendEvents(created.session_id(), {TimeEvent(1, 3)});
  EXPECT_EQ(after.scene().time().phase(), 3u) << after.scene().time().DebugString();
  EXPECT_NEAR(std::abs(SphereColumn(client, created.session_id(), volume) - first), 3.0, 1e-6)
      << "three phases on, the sphere is three voxels along";

  auto stream = client.Attach(created.session_id());
  stream->Send(TimeEvent(2, 2));
  EXPECT_TRUE(WaitFrame(
      *stream, [](const v1::Frame& f) { return f.phase() == 2; }, 60s))
      << "a frame shows phase 2";

  // Playing at 20 phases a second: the frames go through the phases and loop.
  stream->Send(TimeEvent(3, 0, true, 20));
  std::set<std::uint32_t> shown;
  const auto until = std::chrono::steady_clock::now() + 60s;
  while (shown.size() < 5 && std::chrono::steady_clock::now() < until) {
    if (auto frame = WaitFrame(
            *stream, [](const v1::Frame&) { return true; }, 10s)) {
      shown.insert(frame->phase());
    }
  }
  EXPECT_EQ(shown.size(), 5u) << "every phase was shown while playing";

  // What does not fit the series: refused, the session as it was.
  ExpectRpcError([&] { client.SendEvents(created.session_id(), {TimeEvent(4, 5)}); },
                 grpc::StatusCode::INVALID_ARGUMENT, "past the volume's last phase");
  ExpectRpcError([&] { client.SendEvents(created.session_id(), {TimeEvent(5, 0, true, 1000)}); },
                 grpc::StatusCode::INVALID_ARGUMENT, "phases_per_second");
  const auto still = client.CreateSession(SmallSession());
  ExpectRpcError([&] { client.SendEvents(still.session_id(), {TimeEvent(1, 0, true)}); },
                 grpc::StatusCode::INVALID_ARGUMENT, "not a time series");
}

// Phases whose voxels are alike share one Volume (one host and one device
// copy): a sphere that moves every second phase holds three phases' memory
// for six, and still shows each phase.
TEST(TimeSeriesSession, PhasesAlikeShareOneVolume) {
  const auto ramp = [](float top) {
    std::vector<float> values(27);
    for (std::size_t i = 0; i < values.size(); ++i) values[i] = top * float(i) / 26.0f;
    return Volume({3, 3, 3}, {1, 1, 1}, values, {});
  };
  std::vector<Volume> phases;
  for (float top : {100.0f, 200.0f, 100.0f, 100.0f}) phases.push_back(ramp(top));
  const auto shared = service::ShareAlikePhases(std::move(phases));
  ASSERT_EQ(shared.size(), 4u);
  EXPECT_NE(shared[0], shared[1]);
  EXPECT_EQ(shared[0], shared[2]);
  EXPECT_EQ(shared[0], shared[3]);

  ScratchDir scratch;
  MovingSphere pairs;
  pairs.phases = 6;
  pairs.moves_every = 2;
  WriteMovingSphere(scratch / "pairs.nii", pairs);
  MovingSphere every;
  every.phases = 6;
  WriteMovingSphere(scratch / "every.nii", every);
  ServerProcess server(scratch.path(), {"--data-root", scratch.path().string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const v1::VolumeInfo alike = client.LoadVolume("pairs.nii");
  const v1::VolumeInfo distinct = client.LoadVolume("every.nii");
  EXPECT_EQ(alike.phases(), 6u);
  EXPECT_EQ(2 * alike.memory_bytes(), distinct.memory_bytes()) << "three distinct phases of six";

  v1::CreateSessionRequest request = SmallSession("ct-bone", 64, 48);
  request.set_volume_id(alike.id());
  const std::string session = client.CreateSession(request).session_id();
  double column[6];
  for (int k = 0; k < 6; ++k) {
    client.SendEvents(session, {TimeEvent(std::uint64_t(k + 1), k)});
    column[k] = SphereColumn(client, session, alike);
  }
  for (int k : {0, 2, 4}) {
    EXPECT_NEAR(column[k + 1], column[k], 1e-6) << "phases " << k << " and " << k + 1 << " are alike";
    if (k > 0) {
      EXPECT_NEAR(std::abs(column[k] - column[k - 2]), 1.0, 1e-6) << "a voxel along every second phase";
    }
  }
}

// A series past the session's budget for phase copies plays from a window:
// the device holds the phase shown and the one after it (the budget holds two
// of six), never the whole series, and every phase still shows while
// playing; a budget that holds fewer than two is refused at creation.
TEST(TimeSeriesSession, ASeriesPastItsBudgetPlaysFromAWindow) {
  ScratchDir scratch;
  MovingSphere big;
  big.size = 96;  // a phase's copy about 1.8 MiB: float voxels quantised to 16 bits (an int16 phase needs no copy)
  big.float_voxels = true;
  big.phases = 6;
  big.first_x = 40;
  WriteMovingSphere(scratch / "big.nii", big);
  ServerProcess server(scratch.path(), {"--data-root", scratch.path().string(), "--max-phase-copies-mb", "4"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const v1::VolumeInfo volume = client.LoadVolume("big.nii");
  v1::CreateSessionRequest request = SmallSession("ct-bone", 64, 48);
  request.set_volume_id(volume.id());
  const auto created = client.CreateSession(request);
  auto stream = client.Attach(created.session_id());
  stream->Send(TimeEvent(1, 0, true, 20));
  std::set<std::uint32_t> shown;
  std::uint32_t most_copies = 0;
  const auto until = std::chrono::steady_clock::now() + 60s;
  while (shown.size() < 6 && std::chrono::steady_clock::now() < until) {
    if (auto frame = WaitFrame(
            *stream, [](const v1::Frame&) { return true; }, 10s)) {
      shown.insert(frame->phase());
    }
    most_copies = std::max(most_copies, client.Status().devices(0).volume_copies());
  }
  EXPECT_EQ(shown.size(), 6u) << "every phase was shown while playing";
  EXPECT_GE(most_copies, 2u);
  EXPECT_LE(most_copies, 3u) << "the window of two, and the renderer's phase while it switches";

  ServerProcess tight(scratch.path(), {"--data-root", scratch.path().string(), "--max-phase-copies-mb", "2"});
  ASSERT_TRUE(tight.running()) << tight.Log();
  Client tight_client = tight.Connect();
  request.set_volume_id(tight_client.LoadVolume("big.nii").id());
  ExpectRpcError([&] { tight_client.CreateSession(request); }, grpc::StatusCode::RESOURCE_EXHAUSTED,
                 "--max-phase-copies-mb");
}

}  // namespace
}  // namespace cinevol::testing
