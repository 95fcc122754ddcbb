// Several servers behind one client (issue 23): two real cinevol-server
// processes on loopback stand in for two pods. A new session goes to the
// server with the most room, its answer says where it lives, and when its
// server dies the client's stream creates it again, from its last state, on
// the other one.
#include <gtest/gtest.h>

#include <algorithm>
#include <csignal>
#include <thread>

#include "server_process.h"
#include "service_test_support.h"
#include "session_state.h"
#include "sharing_calls.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

// A server on a port chosen up front, so that it can advertise it.
std::unique_ptr<ServerProcess> AdvertisingServer(const std::filesystem::path& scratch, std::vector<std::string> extra) {
  const int port = FreePort();
  extra.insert(extra.end(), {"--advertise-address", "127.0.0.1:" + std::to_string(port)});
  return std::make_unique<ServerProcess>(scratch, extra, "cpu", 0, port);
}

// Servers A and B, each with its own folder under `scratch`.
struct TwoServers {
  std::unique_ptr<ServerProcess> a, b;
};

TwoServers StartTwo(const std::filesystem::path& scratch, const std::vector<std::string>& a_flags,
                    const std::vector<std::string>& b_flags) {
  std::filesystem::create_directories(scratch / "a");
  std::filesystem::create_directories(scratch / "b");
  return {AdvertisingServer(scratch / "a", a_flags), AdvertisingServer(scratch / "b", b_flags)};
}

Client ConnectToBoth(const ServerProcess& a, const ServerProcess& b) {
  ClientOptions options;
  options.address = a.address() + "," + b.address();
  return Client(options);
}

bool Holds(const ServerProcess& server, const std::string& session_id) {
  Client client = server.Connect();
  return FindSessionStatus(client, session_id).has_value();
}

TEST(Placement, ANewSessionGoesWhereThereIsMostRoomAndItsAnswerSaysWhere) {
  ScratchDir scratch;
  auto [a, b] = StartTwo(scratch.path(), {"--max-sessions", "4"}, {"--max-sessions", "3"});
  ASSERT_TRUE(a->running() && b->running()) << a->Log() << b->Log();
  Client only_a = a->Connect();
  Client both = ConnectToBoth(*a, *b);

  const v1::ServerStatus idle = only_a.Status();
  EXPECT_EQ(idle.max_sessions(), 4u);
  EXPECT_EQ(idle.sessions_held(), 0u);
  EXPECT_TRUE(idle.accepting_sessions());

  // A has 4 free places and B 3: A first; then A has 3, B 3: A again (the list breaks ties)...
  const auto first = both.CreateSession(SmallSession());
  EXPECT_EQ(first.address(), a->address()) << "the answer names the server that holds it";
  EXPECT_TRUE(Holds(*a, first.session_id()));
  const auto second = both.CreateSession(SmallSession());
  EXPECT_EQ(second.address(), a->address());
  // ... and now B, with 3 free to A's 2.
  const auto third = both.CreateSession(SmallSession());
  EXPECT_EQ(third.address(), b->address());
  EXPECT_TRUE(Holds(*b, third.session_id()));
  EXPECT_FALSE(Holds(*a, third.session_id()));

  // The session's own calls go where it lives.
  auto stream = both.Attach(third.session_id());
  EXPECT_TRUE(WaitFrame(
      *stream, [](const v1::Frame&) { return true; }, 30s))
      << b->Log();
  v1::SnapshotRequest still;
  still.set_session_id(third.session_id());
  still.set_spp(1);
  EXPECT_GT(both.Snapshot(still).image().size(), 0u);
  stream->Cancel();

  // A full server is passed over, and a full fleet refuses with both reasons.
  Client only_b = b->Connect();
  only_b.CreateSession(SmallSession());
  only_b.CreateSession(SmallSession());
  EXPECT_FALSE(only_b.Status().accepting_sessions());
  EXPECT_EQ(both.CreateSession(SmallSession()).address(), a->address());
  EXPECT_EQ(both.CreateSession(SmallSession()).address(), a->address());  // A's fourth
  ExpectRpcError([&] { both.CreateSession(SmallSession()); }, grpc::StatusCode::RESOURCE_EXHAUSTED,
                 "no server took the session");

  both.CloseSession(third.session_id());
  EXPECT_FALSE(Holds(*b, third.session_id())) << "CloseSession went to the wrong server";
}

TEST(Placement, SessionsCreatedAtOnceSpreadOverTheServers) {
  ScratchDir scratch;
  auto [a, b] = StartTwo(scratch.path(), {"--max-sessions", "8"}, {"--max-sessions", "8"});
  ASSERT_TRUE(a->running() && b->running()) << a->Log() << b->Log();
  Client both = ConnectToBoth(*a, *b);
  std::vector<std::string> addresses(8);
  std::vector<std::thread> threads;
  for (std::size_t i = 0; i < addresses.size(); ++i) {
    threads.emplace_back([&, i] { addresses[i] = both.CreateSession(SmallSession()).address(); });
  }
  for (std::thread& t : threads) t.join();
  const auto on_a = std::count(addresses.begin(), addresses.end(), a->address());
  const auto on_b = std::count(addresses.begin(), addresses.end(), b->address());
  EXPECT_EQ(on_a + on_b, 8);
  EXPECT_LE(std::abs(on_a - on_b), 2) << on_a << " on A, " << on_b << " on B";
}

TEST(Placement, AServerThatIsDownIsPassedOver) {
  ScratchDir scratch;
  auto b = AdvertisingServer(scratch.path(), {});
  ASSERT_TRUE(b->running()) << b->Log();
  ClientOptions options;
  options.address = "127.0.0.1:" + std::to_string(FreePort()) + "," + b->address();  // nothing on the first
  const auto start = std::chrono::steady_clock::now();
  Client client(options);
  EXPECT_LT(std::chrono::steady_clock::now() - start, 2s) << "the dead first server used up the connect timeout";
  EXPECT_FALSE(client.ListVolumes().empty()) << "volume calls go to the server that answered";
  EXPECT_EQ(client.CreateSession(SmallSession()).address(), b->address());
}

TEST(Placement, WhenTheFirstServerGoesVolumeAndStatusCallsGoToAnother) {
  ScratchDir scratch;
  WriteSmallNrrd(scratch / "small.nrrd");
  std::filesystem::create_directories(scratch / "local");
  const std::vector<std::string> flags{"--data-root", scratch.path().string()};
  auto [a, b] = StartTwo(scratch.path(), flags, flags);
  ASSERT_TRUE(a->running() && b->running()) << a->Log() << b->Log();
  Client both = ConnectToBoth(*a, *b);
  const v1::VolumeInfo volume = both.LoadVolume("small.nrrd");  // on A, with a segmentation uploaded
  WriteSmallNrrd(scratch / "local" / "labels.nrrd");
  both.UploadLabels(volume.id(), scratch / "local" / "labels.nrrd");

  ASSERT_EQ(kill(a->pid(), SIGKILL), 0);
  EXPECT_TRUE(both.Status().accepting_sessions()) << "the status of B";
  const v1::VolumeInfo on_b = both.DescribeVolume(volume.id());
  EXPECT_NE(on_b.source().find("small.nrrd"), std::string::npos)
      << "the volume, loaded on B as the client had loaded it on A";
  EXPECT_GT(on_b.labels().names_size(), 0) << "and its segmentation, uploaded again";
  v1::CreateSessionRequest request = SmallSession();
  request.set_volume_id(volume.id());
  EXPECT_EQ(both.CreateSession(request).address(), b->address());
  a.reset();  // already dead: Stop finds it gone
}

TEST(Failover, WhenItsServerDiesTheStreamCreatesTheSessionAgainFromItsLastStateOnAnother) {
  ScratchDir scratch;
  WriteSmallNrrd(scratch / "small.nrrd");
  const std::vector<std::string> flags{"--data-root", scratch.path().string()};
  auto [a, b] = StartTwo(scratch.path(), flags, flags);
  ASSERT_TRUE(a->running() && b->running()) << a->Log() << b->Log();
  Client both = ConnectToBoth(*a, *b);

  // A volume the client loaded (only A has it), and a session of it on A.
  const v1::VolumeInfo volume = both.LoadVolume("small.nrrd");
  v1::CreateSessionRequest request = SmallSession("ct-bone", 96, 64, 4);
  request.set_volume_id(volume.id());
  const auto created = both.CreateSession(request);
  ASSERT_EQ(created.address(), a->address());
  StreamOptions options;
  options.resume_timeout = 1s;  // a dead server is given up on soon
  auto stream = both.Attach(created.session_id(), options);
  ASSERT_TRUE(WaitFrame(
      *stream, [](const v1::Frame&) { return true; }, 30s))
      << a->Log();

  // The state to carry over: a new camera, a new viewport, new stream settings.
  v1::SessionEvent camera = Orbit(9);
  stream->Send(camera);
  v1::SessionEvent resize;
  resize.mutable_resize()->set_width(72);
  resize.mutable_resize()->set_height(40);
  stream->Send(resize);
  v1::SessionEvent quality;
  quality.mutable_stream()->set_jpeg_quality(55);
  const std::uint64_t last = stream->Send(quality);
  ASSERT_TRUE(WaitFrame(
      *stream, [&](const v1::Frame& f) { return f.last_event_seq() >= last; }, 30s));
  // The server's state came before that frame: the events applied as it applies them.
  const std::optional<v1::SessionState> on_a = stream->state();
  ASSERT_TRUE(on_a);
  EXPECT_GE(on_a->last_event_seq(), last);
  EXPECT_EQ(on_a->viewport().width(), 72u);
  EXPECT_EQ(on_a->scene().render().width(), 72u);
  EXPECT_EQ(on_a->stream().jpeg_quality(), 55u);
  EXPECT_EQ(on_a->scene().camera().eye().x(), camera.camera().eye().x());

  const auto killed = std::chrono::steady_clock::now();
  ASSERT_EQ(kill(a->pid(), SIGKILL), 0);
  const auto after = WaitFrame(
      *stream, [&](const v1::Frame&) { return stream->failovers() > 0; }, 60s);
  ASSERT_TRUE(after) << "no frame after the failover; stream status: " << stream->status().error_message();
  RecordProperty("seconds_from_sigkill_to_a_frame_from_the_other_server",
                 std::to_string(std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count()));
  EXPECT_EQ(stream->failovers(), 1);
  EXPECT_EQ(after->width(), 72u);
  EXPECT_EQ(after->height(), 40u);
  const std::string moved = stream->session_id();
  EXPECT_NE(moved, created.session_id());
  EXPECT_TRUE(Holds(*b, moved));

  // The same scene as a session created on B with the events applied:
  // stills of the two match pixel for pixel; without the camera they differ.
  Client only_b = b->Connect();
  SessionState expected(request, created);
  expected.Adopt(*on_a);
  v1::CreateSessionRequest direct = expected.request();
  direct.set_volume_id(only_b.ListVolumes().back().id());
  const auto twin = only_b.CreateSession(direct);
  v1::SnapshotRequest still;
  still.set_spp(2);
  still.set_session_id(created.session_id());  // the client follows the session to B
  const std::string moved_image = both.Snapshot(still).image();
  still.set_session_id(twin.session_id());
  EXPECT_EQ(moved_image, only_b.Snapshot(still).image());
  v1::CreateSessionRequest unmoved = direct;
  *unmoved.mutable_scene()->mutable_camera() = created.scene().camera();
  still.set_session_id(only_b.CreateSession(unmoved).session_id());
  EXPECT_NE(moved_image, only_b.Snapshot(still).image());

  both.CloseSession(created.session_id());
  EXPECT_FALSE(Holds(*b, moved));
  a.reset();  // already dead: Stop finds it gone
}

// Failover keeps the board together: the owner's client restores its grants
// where the session moves, and viewers watching by a link follow it there.
TEST(Failover, ViewersOfASharedSessionFollowItToAnotherServer) {
  ScratchDir scratch;
  auto [a, b] = StartTwo(scratch.path(), {}, {});
  ASSERT_TRUE(a->running() && b->running()) << a->Log() << b->Log();
  Client owner = ConnectToBoth(*a, *b);
  const auto created = owner.CreateSession(SmallSession("ct-bone", 96, 64, 4));
  const bool on_a = created.address() == a->address();
  ServerProcess& holder = on_a ? *a : *b;
  StreamOptions options;
  options.resume_timeout = 1s;  // a dead server is given up on soon
  auto stream = owner.Attach(created.session_id(), options);
  ASSERT_TRUE(WaitFrame(
      *stream, [](const v1::Frame&) { return true; }, 30s))
      << holder.Log();
  v1::ShareSessionRequest share;
  share.set_session_id(created.session_id());
  const v1::Grant link = owner.Share(share);

  // Viewers who know both servers (the deployment's address), not where the session is.
  std::vector<std::unique_ptr<Client>> people;
  std::vector<std::unique_ptr<SessionWatch>> viewers;
  for (int i = 0; i < 3; ++i) {
    people.push_back(std::make_unique<Client>(ConnectToBoth(*a, *b)));
    viewers.push_back(people.back()->Watch(link.secret()));
  }
  auto frame_after = [](SessionWatch& watch, const std::function<bool()>& when) -> bool {
    for (int i = 0; i < 2000; ++i) {
      const auto message = watch.Next(100ms);
      if (message && message->has_frame() && when()) return true;
      if (!message && watch.ended()) return false;
    }
    return false;
  };
  for (auto& v : viewers) ASSERT_TRUE(frame_after(*v, [] { return true; })) << v->status().error_message();

  ASSERT_EQ(kill(holder.pid(), SIGKILL), 0);
  ASSERT_TRUE(WaitFrame(
      *stream, [&](const v1::Frame&) { return stream->failovers() > 0; }, 60s))
      << stream->status().error_message();
  for (auto& v : viewers) {
    const SessionWatch& watch = *v;
    EXPECT_TRUE(frame_after(*v, [&] { return watch.follows() > 0; }))
        << "the viewer did not follow the session: " << v->status().error_message();
  }
  EXPECT_TRUE(Holds(on_a ? *b : *a, stream->session_id()));
  (on_a ? a : b).reset();  // already dead: Stop finds it gone
}

// An upgrade: the pod drains (SIGTERM) and its sessions move, without
// waiting out the resume timeout: the draining server's trailers say the
// session ended, so there is nothing to resume.
TEST(Failover, ADrainingServersSessionsMoveToAnotherAtOnce) {
  ScratchDir scratch;
  auto [a, b] = StartTwo(scratch.path(), {"--drain-seconds", "3"}, {});
  ASSERT_TRUE(a->running() && b->running()) << a->Log() << b->Log();
  Client both = ConnectToBoth(*a, *b);
  const auto created = both.CreateSession(SmallSession());
  ASSERT_EQ(created.address(), a->address());
  auto stream = both.Attach(created.session_id());  // the default resume timeout, 5 s
  ASSERT_TRUE(WaitFrame(
      *stream, [](const v1::Frame&) { return true; }, 30s));

  const auto drained = std::chrono::steady_clock::now();
  ASSERT_EQ(kill(a->pid(), SIGTERM), 0);
  const auto after = WaitFrame(
      *stream, [&](const v1::Frame&) { return stream->failovers() > 0; }, 30s);
  ASSERT_TRUE(after) << stream->status().error_message();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - drained).count();
  RecordProperty("seconds_from_sigterm_to_a_frame_from_the_other_server", std::to_string(seconds));
  EXPECT_LT(seconds, 4) << "it waited out the resume timeout";
  EXPECT_TRUE(Holds(*b, stream->session_id()));
}

// A server that stops answering without closing anything (SIGSTOP: its
// kernel still holds the connections, as with a lost node or a network cut):
// keepalive pings find it out, then the session moves.
TEST(Failover, AServerThatHangsIsFoundOutByKeepaliveAndItsSessionsMove) {
  ScratchDir scratch;
  auto [a, b] = StartTwo(scratch.path(), {}, {});
  ASSERT_TRUE(a->running() && b->running()) << a->Log() << b->Log();
  ClientOptions options;
  options.address = a->address() + "," + b->address();
  options.keepalive = 1s;
  options.keepalive_timeout = 1s;
  Client both(options);
  const auto created = both.CreateSession(SmallSession());
  ASSERT_EQ(created.address(), a->address());
  StreamOptions stream_options;
  stream_options.resume_timeout = 1s;
  auto stream = both.Attach(created.session_id(), stream_options);
  ASSERT_TRUE(WaitFrame(
      *stream, [](const v1::Frame&) { return true; }, 30s));

  const auto hung = std::chrono::steady_clock::now();
  ASSERT_EQ(kill(a->pid(), SIGSTOP), 0);
  const auto after = WaitFrame(
      *stream, [&](const v1::Frame&) { return stream->failovers() > 0; }, 30s);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - hung).count();
  kill(a->pid(), SIGKILL);
  ASSERT_TRUE(after) << "no move in 30 s: " << stream->status().error_message();
  RecordProperty("seconds_from_sigstop_to_a_frame_from_the_other_server", std::to_string(seconds));
  EXPECT_TRUE(Holds(*b, stream->session_id()));
}

TEST(Failover, AStreamOfASessionItDidNotCreateEndsAsBefore) {
  ScratchDir scratch;
  auto [a, b] = StartTwo(scratch.path(), {}, {});
  ASSERT_TRUE(a->running() && b->running()) << a->Log() << b->Log();
  Client only_a = a->Connect();
  const auto created = only_a.CreateSession(SmallSession());
  Client both = ConnectToBoth(*a, *b);  // knows nothing of the session's state
  StreamOptions options;
  options.resume_timeout = 500ms;
  auto stream = both.Attach(created.session_id(), options);
  ASSERT_TRUE(WaitFrame(
      *stream, [](const v1::Frame&) { return true; }, 30s));
  ASSERT_EQ(kill(a->pid(), SIGKILL), 0);
  EXPECT_TRUE(Eventually([&] { return stream->ended(); }, 20s));
  EXPECT_EQ(stream->status().error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(stream->failovers(), 0);
}

}  // namespace
}  // namespace cinevol::testing
