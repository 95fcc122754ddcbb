// Slow and vanished clients: a client that stops reading gets nothing
// rendered while its slot is full, costs the server bounded memory and does
// not slow its neighbour; a client killed mid-stream has its session freed.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

// Large, poorly compressible frames fill the transport's buffers quickly.
v1::CreateSessionRequest HeavyFrames() {
  v1::CreateSessionRequest r = SmallSession("ct-bone", 192, 144, 65536);
  r.mutable_stream()->set_jpeg_quality(100);
  r.mutable_stream()->set_chroma(v1::CHROMA_444);
  r.mutable_stream()->set_denoiser(v1::DENOISER_NONE);
  return r;
}

// A stream that attaches and sends events but never reads.
class StalledReader {
 public:
  StalledReader(Client& client, const std::string& session_id)
      : stub_(v1::SessionService::NewStub(client.channel())), stream_(stub_->StreamSession(&context_)) {
    v1::ClientMessage attach;
    attach.mutable_attach()->set_session_id(session_id);
    stream_->Write(attach);
    sender_ = std::thread([this] {
      for (int seq = 1; !stop_; ++seq) {
        v1::ClientMessage m;
        *m.mutable_event() = Orbit(seq);
        m.mutable_event()->set_seq(seq);
        if (!stream_->Write(m)) break;
        std::this_thread::sleep_for(16ms);
      }
    });
  }
  ~StalledReader() {
    stop_ = true;
    context_.TryCancel();
    sender_.join();
  }

 private:
  std::unique_ptr<v1::SessionService::Stub> stub_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::ClientMessage, v1::ServerMessage>> stream_;
  std::atomic<bool> stop_{false};
  std::thread sender_;
};

// Frames rendered for session `id`, or -1 when the server no longer holds it.
std::int64_t FramesRendered(Client& client, const std::string& id) {
  const auto s = FindSessionStatus(client, id);
  return s ? std::int64_t(s->frames_rendered()) : -1;
}

TEST(Backpressure, AStalledReaderGetsNoFramesAndDoesNotSlowItsNeighbour) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto a = client.CreateSession(HeavyFrames());
  const auto b = client.CreateSession(HeavyFrames());
  auto stream_b = client.Attach(b.session_id());

  // The reference: A reads normally beside B.
  double fps_b_beside_reader = 0;
  {
    auto stream_a = client.Attach(a.session_id());
    std::atomic<bool> stop{false};
    std::thread reader_a([&] {
      for (int step = 0; !stop; ++step) {
        stream_a->Send(Orbit(step));
        while (stream_a->Next(16ms)) {
        }
      }
    });
    fps_b_beside_reader = ReadingFps(*stream_b, 3s);
    stop = true;
    reader_a.join();
  }

  // A stops reading: once its transport buffers and slot are full, nothing more renders for it.
  StalledReader stalled(client, a.session_id());
  std::int64_t before = 0;
  const bool stalled_out = Eventually(
      [&] {
        before = FramesRendered(client, a.session_id());
        std::this_thread::sleep_for(1s);
        return before >= 0 && FramesRendered(client, a.session_id()) == before;
      },
      60s);
  ASSERT_TRUE(stalled_out) << "A kept rendering though it reads nothing";
  const double memory_before = server.ResidentMiB();
  const double fps_b_beside_stalled = ReadingFps(*stream_b, 3s);
  EXPECT_LE(FramesRendered(client, a.session_id()), before) << "frames rendered for a full slot";
  EXPECT_LT(server.ResidentMiB() - memory_before, 32.0) << "server memory grew while A was stalled";
  EXPECT_GE(fps_b_beside_stalled, 0.8 * fps_b_beside_reader)
      << "B's frame rate dropped: " << fps_b_beside_stalled << " fps beside a stalled reader, "
      << fps_b_beside_reader << " beside a reading one";
  const auto status_a = FindSessionStatus(client, a.session_id());
  ASSERT_TRUE(status_a);
  EXPECT_GT(status_a->frames_dropped() + status_a->frames_sent(), 0u);
  std::printf("B: %.1f fps beside a reading A, %.1f beside a stalled A; A: %llu rendered, %llu sent, %llu dropped\n",
              fps_b_beside_reader, fps_b_beside_stalled, (unsigned long long)status_a->frames_rendered(),
              (unsigned long long)status_a->frames_sent(), (unsigned long long)status_a->frames_dropped());
}

TEST(Backpressure, AKilledClientsSessionIsFreed) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--detached-session-seconds", "1"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const pid_t viewer = Spawn(CliPath(), {"loadtest", "--server", server.address(), "--sessions", "1",
                                                "--seconds", "120", "--width", "96", "--height", "64"},
                             scratch / "viewer.log");
  ASSERT_GT(viewer, 0);
  std::string id;
  ASSERT_TRUE(Eventually(
      [&] {
        const v1::ServerStatus s = client.Status();
        if (s.sessions_size() == 1 && s.sessions(0).frames_rendered() > 5) id = s.sessions(0).session_id();
        return !id.empty();
      },
      30s));
  EXPECT_TRUE(FindSessionStatus(client, id)->holds_device_memory());

  kill(viewer, SIGKILL);
  const auto killed = std::chrono::steady_clock::now();
  WaitExit(viewer, 5s);
  EXPECT_TRUE(Eventually(
      [&] {
        const auto s = FindSessionStatus(client, id);
        return !s || !s->holds_device_memory();
      },
      1s))
      << "the killed client's session still holds its memory";
  const double freed_after = std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count();
  EXPECT_TRUE(Eventually([&] { return !FindSessionStatus(client, id); }, 5s)) << "the detached session never expired";
  std::printf("memory freed %.2f s after the kill\n", freed_after);
  EXPECT_TRUE(client.Status().sessions().empty());
}

}  // namespace
}  // namespace cinevol::testing
