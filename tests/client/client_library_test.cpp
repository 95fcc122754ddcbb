// cinevol::Client against a real server: the frame callback and decoding,
// bearer tokens and session ownership, and resuming a stream after the
// connection is cut (through a loopback proxy the test controls).
#include <gtest/gtest.h>

#include <atomic>
#include <fstream>

#include "service/server_process.h"
#include "service/service_test_support.h"
#include "service/tcp_proxy.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

template <class F>
grpc::StatusCode CodeOf(F&& call) {
  try {
    call();
    return grpc::StatusCode::OK;
  } catch (const RpcError& e) {
    return e.code();
  }
}

TEST(ClientLibrary, HandsFramesToACallbackAndDecodesThem) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession());
  std::mutex mu;
  std::vector<v1::Frame> frames;
  int notices = 0;
  StreamOptions options;
  options.on_message = [&](const v1::ServerMessage& m) {
    std::lock_guard lock(mu);
    if (m.has_frame()) frames.push_back(m.frame());
    if (m.has_notice()) ++notices;
  };
  auto stream = client.Attach(created.session_id(), options);
  ASSERT_TRUE(Eventually(
      [&] {
        std::lock_guard lock(mu);
        return !frames.empty() && frames.back().final();
      },
      30s));
  EXPECT_FALSE(stream->Next(100ms)) << "with a callback, nothing queues for Next";
  std::lock_guard lock(mu);
  EXPECT_EQ(notices, 1);
  const RgbImage image = DecodeFrame(frames.back());
  EXPECT_EQ(image.width, 96);
  EXPECT_EQ(image.height, 64);
  EXPECT_EQ(image.rgb.size(), 96u * 64u * 3u);
  v1::Frame broken = frames.back();
  broken.set_jpeg("not a jpeg");
  EXPECT_THROW(DecodeFrame(broken), std::runtime_error);
}

TEST(ClientLibrary, TokensAreCheckedAndSessionsStayWithTheirOwner) {
  ScratchDir scratch;
  std::ofstream(scratch / "tokens") << "# token principal\nalice-token alice\nbob-token bob\n";
  ServerProcess server(scratch.path(), {"--auth-tokens", (scratch / "tokens").string()});
  ASSERT_TRUE(server.running()) << server.Log();

  Client anonymous = server.Connect();
  EXPECT_EQ(CodeOf([&] { anonymous.ListVolumes(); }), grpc::StatusCode::UNAUTHENTICATED);
  Client forger = server.Connect("mallory-token");
  try {
    forger.ListVolumes();
    ADD_FAILURE() << "a forged token was accepted";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::UNAUTHENTICATED);
    EXPECT_NE(std::string(e.what()).find("not valid"), std::string::npos) << e.what();
  }

  Client alice = server.Connect("alice-token"), bob = server.Connect("bob-token");
  const auto created = alice.CreateSession(SmallSession());
  EXPECT_EQ(FindSessionStatus(alice, created.session_id())->owner(), "alice");
  EXPECT_EQ(CodeOf([&] { bob.CloseSession(created.session_id()); }), grpc::StatusCode::PERMISSION_DENIED);
  v1::SnapshotRequest still;
  still.set_session_id(created.session_id());
  still.set_spp(1);
  EXPECT_EQ(CodeOf([&] { bob.Snapshot(still); }), grpc::StatusCode::PERMISSION_DENIED);
  auto stolen = bob.Attach(created.session_id());
  EXPECT_TRUE(Eventually([&] { return stolen->ended(); }, 10s));
  EXPECT_EQ(stolen->status().error_code(), grpc::StatusCode::PERMISSION_DENIED);
  auto own = alice.Attach(created.session_id());
  EXPECT_TRUE(WaitFinal(*own));
  alice.CloseSession(created.session_id());
}

TEST(ClientLibrary, ResumesTheStreamAfterTheConnectionIsCut) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  TcpProxy proxy(server.port());
  ClientOptions options;
  options.address = "127.0.0.1:" + std::to_string(proxy.port());
  Client client(options);
  const auto created = client.CreateSession(SmallSession("ct-bone", 96, 64, 65536));
  auto stream = client.Attach(created.session_id());
  const auto before = WaitFrame(*stream, [](const v1::Frame&) { return true; });
  ASSERT_TRUE(before);

  proxy.CutAll();
  ASSERT_TRUE(Eventually([&] { return stream->resumes() == 1; }, 20s)) << "the stream never reattached";
  EXPECT_FALSE(stream->ended()) << stream->status().error_message();
  EXPECT_GE(proxy.connections_accepted(), 2);
  // The session is the same one: its frames continue, and events apply.
  v1::SessionEvent turn;
  turn.mutable_camera()->set_view(v1::LEFT);
  std::uint64_t seq = 0;
  ASSERT_TRUE(Eventually([&] { return (seq = stream->Send(turn)) != 0; }, 10s));
  const auto after = WaitFrame(*stream, [seq](const v1::Frame& f) { return f.last_event_seq() >= seq; });
  ASSERT_TRUE(after);
  EXPECT_GT(after->frame_id(), before->frame_id());
  EXPECT_EQ(client.Status().sessions_size(), 1);
}

TEST(ClientLibrary, RendersSlicesAndPicksOnASessionAndMapsTheirErrors) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession());  // phantom:head?size=48, 96x64
  v1::SliceRequest slice;
  slice.set_session_id(created.session_id());
  slice.set_axis(v1::CORONAL);
  const v1::SliceImage image = client.RenderSlice(slice);
  EXPECT_EQ(image.width(), 48u);
  EXPECT_FALSE(image.png().empty());
  EXPECT_EQ(image.edge_letters_size(), 4);

  v1::PickRequest pick;
  pick.set_session_id(created.session_id());
  pick.set_x(48);
  pick.set_y(32);
  EXPECT_TRUE(client.Pick(pick).hit()) << "the view's centre is on the head";
  pick.set_x(-3);
  EXPECT_EQ(CodeOf([&] { client.Pick(pick); }), grpc::StatusCode::INVALID_ARGUMENT);
  slice.set_session_id("no-such-session");
  EXPECT_NE(CodeOf([&] { client.RenderSlice(slice); }), grpc::StatusCode::OK);
}

TEST(ClientLibrary, ReportsAServerThatIsDownWithinTheConnectTimeout) {
  ClientOptions options;
  options.address = "127.0.0.1:1";
  options.connect_timeout = 1s;
  const auto start = std::chrono::steady_clock::now();
  try {
    Client client(options);
    ADD_FAILURE() << "connected to nothing";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::UNAVAILABLE);
    EXPECT_NE(std::string(e.what()).find("127.0.0.1:1"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, 5s);
}

}  // namespace
}  // namespace cinevol::testing
