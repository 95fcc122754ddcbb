// Sharing a session (docs/sharing.md): a real cinevol-server on loopback, an
// owner's stream, watchers by grant over the client library's SessionWatch.
// Every wait is bounded by a deadline and a message count.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "metrics_scrape.h"
#include "server_process.h"
#include "service_test_support.h"
#include "sharing_calls.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

constexpr int kMaxMessages = 5000;

// A server with two principals (alice owns, bob is granted, carol is not).
struct TokenServer {
  explicit TokenServer(const std::filesystem::path& scratch, std::vector<std::string> extra = {}) {
    std::ofstream(scratch / "tokens") << "alice-token alice\nbob-token bob\ncarol-token carol\n";
    extra.insert(extra.end(), {"--auth-tokens", (scratch / "tokens").string()});
    server = std::make_unique<ServerProcess>(scratch, extra);
  }
  // A channel with no token at all: what a link's holder has.
  std::shared_ptr<grpc::Channel> Bare() const {
    return grpc::CreateChannel(server->address(), grpc::InsecureChannelCredentials());
  }
  std::unique_ptr<ServerProcess> server;
};

v1::Grant Share(Client& owner, const std::string& session, const std::string& principal, v1::ShareRole role,
                bool allow_pointer = false, std::uint32_t expires_seconds = 0) {
  v1::ShareSessionRequest request;
  request.set_session_id(session);
  request.set_principal(principal);
  request.set_role(role);
  request.set_allow_pointer(allow_pointer);
  request.set_expires_seconds(expires_seconds);
  return owner.Share(request);
}

// The watch's next frame with an id past `after`; none when the call ends or the time runs out.
std::optional<v1::Frame> FrameAfter(SessionWatch& watch, std::uint64_t after, std::chrono::seconds within = 60s) {
  const auto end = std::chrono::steady_clock::now() + within;
  for (int i = 0; i < kMaxMessages && std::chrono::steady_clock::now() < end; ++i) {
    const auto message = watch.Next(1s);
    if (message && message->has_frame() && message->frame().frame_id() > after) return message->frame();
    if (!message && watch.ended()) return std::nullopt;
  }
  return std::nullopt;
}

// Waits for the watch's call to end; its status.
grpc::Status Ended(SessionWatch& watch, std::chrono::seconds within = 30s) {
  const auto end = std::chrono::steady_clock::now() + within;
  for (int i = 0; i < kMaxMessages && std::chrono::steady_clock::now() < end && !watch.ended(); ++i) watch.Next(200ms);
  return watch.ended() ? watch.status() : grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, "still watching");
}

v1::SessionEvent Camera(v1::NamedView view) {
  v1::SessionEvent e;
  e.mutable_camera()->set_view(view);
  return e;
}

v1::SessionEvent Point(float x, float y) {
  v1::SessionEvent e;
  e.mutable_pointer()->set_x(x);
  e.mutable_pointer()->set_y(y);
  return e;
}

void ExpectDenied(const std::function<void()>& call, grpc::StatusCode code, const std::string& text) {
  ExpectRpcError(call, code, text);
}

// One presenter, 20 viewers: every viewer gets the presenter's frames, down
// to the final one, from a single encode per frame; a viewer cannot drive.
TEST(Sharing, TwentyViewersSeeThePresentersFramesEncodedOnce) {
  ScratchDir scratch;
  TokenServer s(scratch.path(), {"--metrics-listen", "127.0.0.1:0"});
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  Client alice = s.server->Connect("alice-token");
  v1::CreateSessionRequest request = SmallSession("ct-bone", 64, 48);
  request.mutable_stream()->set_target_spp(8);
  const auto created = alice.CreateSession(request);
  auto stream = alice.Attach(created.session_id());
  ASSERT_TRUE(WaitFinal(*stream)) << stream->status().error_message();

  const v1::Grant link = Share(alice, created.session_id(), "", v1::VIEWER);
  ASSERT_FALSE(link.secret().empty());
  EXPECT_EQ(s.server->Log().find(link.secret()), std::string::npos) << "a secret is never logged";
  const auto bare = s.Bare();
  std::vector<std::unique_ptr<SessionWatch>> viewers;
  for (int i = 0; i < 20; ++i) viewers.push_back(std::make_unique<SessionWatch>(std::vector{bare}, link.secret(), ""));
  for (auto& v : viewers) ASSERT_TRUE(FrameAfter(*v, 0)) << "the newest frame at once: " << v->status().error_message();

  // The presenter moves; every viewer receives that refinement's final frame.
  ASSERT_GT(stream->Send(Camera(v1::LEFT)), 0u);
  const auto final_frame = WaitFinal(*stream, 1);
  ASSERT_TRUE(final_frame) << stream->status().error_message();
  for (auto& v : viewers) {
    std::optional<v1::Frame> seen;
    for (int i = 0; i < 200 && (!seen || seen->frame_id() < final_frame->frame_id()); ++i) {
      seen = FrameAfter(*v, seen ? seen->frame_id() : 0, 30s);
      if (!seen) break;
    }
    ASSERT_TRUE(seen) << v->status().error_message();
    EXPECT_EQ(seen->frame_id(), final_frame->frame_id());
    EXPECT_EQ(seen->jpeg(), final_frame->jpeg()) << "the same bytes: encoded once";
    EXPECT_EQ(v->state()->viewers(), 20u);
    EXPECT_EQ(v->state()->presenter(), "alice");
  }
  ExpectDenied([&] { viewers[0]->Send({Camera(v1::RIGHT)}); }, grpc::StatusCode::PERMISSION_DENIED,
               "only event is its pointer");
  ExpectDenied([&] { viewers[0]->Send({Point(0.5f, 0.5f)}); }, grpc::StatusCode::PERMISSION_DENIED, "allow_pointer");

  // Encodes are counted per frame rendered, not per frame sent.
  const int port = MetricsPort(*s.server);
  ASSERT_GT(port, 0) << s.server->Log();
  const std::string text = HttpGet(port, "/metrics").value_or("");
  const double rendered = Sample(text, "cinevol_frames_rendered_total");
  const double encoded = Sample(text, R"(cinevol_stage_seconds_count{stage="encode"})");
  const double sent = Sample(text, "cinevol_frames_sent_total");
  EXPECT_GT(rendered, 0) << text;
  EXPECT_EQ(encoded, rendered) << text;
  EXPECT_GT(sent, 10 * rendered) << "twenty viewers and the presenter each sent most frames: " << text;
}

// Grants are checked like tokens: a principal's grant needs that principal,
// a session without a grant its owner; revoking or expiry ends the streams.
TEST(Sharing, GrantsAreCheckedAndRevokingOrExpiryEndsTheirStreams) {
  ScratchDir scratch;
  TokenServer s(scratch.path());
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  Client alice = s.server->Connect("alice-token");
  Client bob = s.server->Connect("bob-token");
  Client carol = s.server->Connect("carol-token");
  const auto created = alice.CreateSession(SmallSession());
  auto stream = alice.Attach(created.session_id());
  ASSERT_TRUE(WaitFinal(*stream)) << stream->status().error_message();

  const v1::Grant for_bob = Share(alice, created.session_id(), "bob", v1::VIEWER);
  EXPECT_EQ(for_bob.principal(), "bob");
  ExpectDenied([&] { Share(bob, created.session_id(), "carol", v1::VIEWER); }, grpc::StatusCode::PERMISSION_DENIED,
               "another user");
  auto bobs = bob.Watch(for_bob.secret());
  ASSERT_TRUE(FrameAfter(*bobs, 0)) << bobs->status().error_message();
  auto carols = carol.Watch(for_bob.secret());
  EXPECT_EQ(Ended(*carols).error_code(), grpc::StatusCode::PERMISSION_DENIED) << "bob's grant is not carol's";
  auto tokenless = SessionWatch({s.Bare()}, for_bob.secret(), "");
  EXPECT_EQ(Ended(tokenless).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  auto forged = carol.Watch(for_bob.secret().substr(0, for_bob.secret().size() - 1) + "0");
  EXPECT_EQ(Ended(*forged).error_code(), grpc::StatusCode::PERMISSION_DENIED);
  {  // and without a grant, carol cannot watch alice's session by its id
    grpc::ClientContext context;
    context.AddMetadata("authorization", "Bearer carol-token");
    context.set_deadline(std::chrono::system_clock::now() + 30s);
    v1::WatchSessionRequest by_id;
    by_id.set_session_id(created.session_id());
    auto reader = v1::SessionService::NewStub(s.Bare())->WatchSession(&context, by_id);
    v1::ServerMessage ignored;
    for (int i = 0; i < kMaxMessages && reader->Read(&ignored); ++i) {
    }
    EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::PERMISSION_DENIED);
  }

  const auto listed = alice.ListShares(created.session_id());
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_TRUE(listed[0].secret().empty()) << "a list never shows secrets";
  EXPECT_EQ(listed[0].watching(), 1u);
  EXPECT_EQ(alice.RevokeShare(created.session_id(), for_bob.id()), 1u);
  const grpc::Status revoked = Ended(*bobs);
  EXPECT_EQ(revoked.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_NE(revoked.error_message().find("revoked"), std::string::npos) << revoked.error_message();
  EXPECT_EQ(Ended(*bob.Watch(for_bob.secret())).error_code(), grpc::StatusCode::PERMISSION_DENIED);

  const v1::Grant brief = Share(alice, created.session_id(), "", v1::VIEWER, false, 2);
  auto watcher = SessionWatch({s.Bare()}, brief.secret(), "");
  ASSERT_TRUE(FrameAfter(watcher, 0)) << watcher.status().error_message();
  const grpc::Status expired = Ended(watcher);
  EXPECT_EQ(expired.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_NE(expired.error_message().find("expired"), std::string::npos) << expired.error_message();
  EXPECT_FALSE(stream->ended()) << "the owner's stream goes on";
}

// A presenter drives; the role is handed over and back; pointers are shared.
TEST(Sharing, APresenterDrivesHandsOverAndPointersReachEveryone) {
  ScratchDir scratch;
  TokenServer s(scratch.path());
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  Client alice = s.server->Connect("alice-token");
  Client bob = s.server->Connect("bob-token");
  const auto created = alice.CreateSession(SmallSession());
  auto stream = alice.Attach(created.session_id());
  ASSERT_TRUE(WaitFinal(*stream)) << stream->status().error_message();

  const v1::Grant presenter = Share(alice, created.session_id(), "bob", v1::PRESENTER);
  const v1::Grant pointing = Share(alice, created.session_id(), "", v1::VIEWER, /*allow_pointer=*/true);
  auto bobs = bob.Watch(presenter.secret());
  auto viewer = SessionWatch({s.Bare()}, pointing.secret(), "");
  ASSERT_TRUE(FrameAfter(*bobs, 0)) << bobs->status().error_message();
  ASSERT_TRUE(FrameAfter(viewer, 0)) << viewer.status().error_message();

  const v1::SessionState driven = bobs->Send({Camera(v1::SUPERIOR)});
  EXPECT_EQ(driven.presenter(), "bob");
  EXPECT_GT(driven.scene().camera().eye().z(), driven.scene().camera().target().z()) << "from above, as numbers";
  const auto answered =
      WaitFrame(*stream, [&](const v1::Frame& f) { return f.last_event_seq() >= driven.last_event_seq(); });
  EXPECT_TRUE(answered) << "the owner sees the presenter's move: " << stream->status().error_message();

  const v1::SessionState pointed = viewer.Send({Point(0.25f, 0.75f)});
  ASSERT_EQ(pointed.pointers_size(), 1);
  EXPECT_EQ(pointed.pointers(0).who(), "link " + pointing.id());
  EXPECT_FLOAT_EQ(pointed.pointers(0).x(), 0.25f);
  EXPECT_TRUE(Eventually([&] { return stream->state() && stream->state()->pointers_size() == 1; }, 10s))
      << "the owner's stream hears of it";
  ExpectDenied([&] { viewer.Send({Point(2, 0)}); }, grpc::StatusCode::INVALID_ARGUMENT, "pointer");

  // The owner's measurements reach every watcher through the state.
  v1::SessionEvent measured;
  v1::Measurement* m = measured.mutable_measurements()->add_measurements();
  for (float z : {0.0f, 42.0f}) {
    v1::Vec3* p = m->add_points();
    p->set_z(z);
  }
  ASSERT_GT(stream->Send(measured), 0u);
  EXPECT_TRUE(Eventually([&] { return viewer.state() && viewer.state()->scene().measurements_size() == 1; }, 10s))
      << "the viewer's state carries the owner's measurement";
  ExpectDenied([&] { viewer.Send({measured}); }, grpc::StatusCode::PERMISSION_DENIED, "viewer's");

  v1::HandOverRequest back;
  back.set_session_id(created.session_id());
  EXPECT_EQ(alice.HandOver(back), "alice");
  ExpectDenied([&] { bobs->Send({Camera(v1::LEFT)}); }, grpc::StatusCode::PERMISSION_DENIED, "viewer's");
  v1::HandOverRequest to_link;
  to_link.set_session_id(created.session_id());
  to_link.set_grant_id(pointing.id());
  EXPECT_EQ(alice.HandOver(to_link), "link " + pointing.id());
  const v1::Camera right = viewer.Send({Camera(v1::RIGHT)}).scene().camera();
  EXPECT_LT(right.eye().x(), right.target().x()) << "the link drives now: from the patient's right";

  // A watcher that leaves takes its pointer with it.
  viewer.Cancel();
  EXPECT_TRUE(Eventually([&] { return stream->state() && stream->state()->pointers_size() == 0; }, 10s))
      << "a departed viewer's pointer stays on everyone's screen";
}

// A viewer that stops reading costs only its own frames.
TEST(Sharing, AViewerThatStopsReadingDoesNotSlowThePresenter) {
  ScratchDir scratch;
  TokenServer s(scratch.path());
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  Client alice = s.server->Connect("alice-token");
  const auto created = alice.CreateSession(SmallSession("ct-bone", 160, 120));
  auto stream = alice.Attach(created.session_id());
  ASSERT_TRUE(WaitFinal(*stream)) << stream->status().error_message();
  const v1::Grant link = Share(alice, created.session_id(), "", v1::VIEWER);
  // A raw call nobody reads: its transport fills, its slot keeps the newest frame.
  grpc::ClientContext stuck_context;
  auto stub = v1::SessionService::NewStub(s.Bare());
  v1::WatchSessionRequest watch;
  watch.set_grant(link.secret());
  auto stuck = stub->WatchSession(&stuck_context, watch);

  std::uint64_t last_seq = 0;
  for (int step = 0; step < 40; ++step) last_seq = stream->Send(Orbit(step));
  const auto answered = WaitFrame(*stream, [&](const v1::Frame& f) { return f.last_event_seq() >= last_seq; });
  EXPECT_TRUE(answered) << "the presenter's frames go on: " << stream->status().error_message();
  stuck_context.TryCancel();
}

// Limits: viewers per session and per grant (one link never takes every
// seat), grants per principal; bad requests named.
TEST(Sharing, LimitsAndBadRequestsAreRefusedByName) {
  ScratchDir scratch;
  TokenServer s(scratch.path(), {"--max-viewers-per-session", "3", "--max-viewers-per-grant", "2",
                                 "--max-grants-per-principal", "3"});
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  Client alice = s.server->Connect("alice-token");
  const auto created = alice.CreateSession(SmallSession());
  auto stream = alice.Attach(created.session_id());
  ASSERT_TRUE(WaitFinal(*stream)) << stream->status().error_message();
  const v1::Grant link = Share(alice, created.session_id(), "", v1::VIEWER);
  auto one = SessionWatch({s.Bare()}, link.secret(), ""), two = SessionWatch({s.Bare()}, link.secret(), "");
  ASSERT_TRUE(FrameAfter(one, 0) && FrameAfter(two, 0));
  auto three = SessionWatch({s.Bare()}, link.secret(), "");
  const grpc::Status link_full = Ended(three);
  EXPECT_EQ(link_full.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(link_full.error_message().find("--max-viewers-per-grant"), std::string::npos) << link_full.error_message();
  const v1::Grant another = Share(alice, created.session_id(), "", v1::VIEWER);
  auto four = SessionWatch({s.Bare()}, another.secret(), "");
  ASSERT_TRUE(FrameAfter(four, 0)) << "another link still gets a seat";
  auto five = SessionWatch({s.Bare()}, another.secret(), "");
  const grpc::Status full = Ended(five);
  EXPECT_EQ(full.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(full.error_message().find("--max-viewers-per-session"), std::string::npos) << full.error_message();

  Share(alice, created.session_id(), "bob", v1::VIEWER);
  ExpectDenied([&] { Share(alice, created.session_id(), "carol", v1::VIEWER); }, grpc::StatusCode::RESOURCE_EXHAUSTED,
               "--max-grants-per-principal");
  ExpectDenied([&] { Share(alice, created.session_id(), "", v1::VIEWER, false, 700000); },
               grpc::StatusCode::INVALID_ARGUMENT, "expires_seconds");
  ExpectDenied([&] { alice.RevokeShare(created.session_id(), "gnope"); }, grpc::StatusCode::NOT_FOUND, "grant_id");
  v1::ShareSessionRequest restore;
  restore.set_session_id(created.session_id());
  restore.set_restore_secret("cvg_g1234_short");
  ExpectDenied([&] { alice.Share(restore); }, grpc::StatusCode::INVALID_ARGUMENT, "restore_secret");
  restore.set_restore_secret(link.secret());  // a grant this server holds already
  ExpectDenied([&] { alice.Share(restore); }, grpc::StatusCode::INVALID_ARGUMENT, "held here already");
  // The session's end ends its watchers and forgets its grants.
  alice.CloseSession(created.session_id());
  EXPECT_TRUE(Ended(one).ok() || Ended(one).error_code() != grpc::StatusCode::DEADLINE_EXCEEDED);
  EXPECT_EQ(Ended(*alice.Watch(link.secret())).error_code(), grpc::StatusCode::PERMISSION_DENIED);
}

}  // namespace
}  // namespace cinevol::testing
