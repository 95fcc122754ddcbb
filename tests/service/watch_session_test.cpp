// WatchSession and SendEvents, the session calls for clients that cannot
// stream both ways: a real cinevol-server on loopback, the raw stubs (the
// client library does not wrap them), every read bounded by a deadline and a
// message count.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

constexpr int kMaxMessages = 5000;  // what a wait reads at most before it gives up

// The state gives a named view as numbers: the eye on the patient's left
// (+x, LPS) of the target.
bool FromTheLeft(const v1::Camera& camera) {
  return camera.view() == v1::NAMED_VIEW_UNSPECIFIED && camera.eye().x() > camera.target().x();
}

void Authorize(grpc::ClientContext& context, const std::string& token) {
  if (!token.empty()) context.AddMetadata("authorization", "Bearer " + token);
}

// A WatchSession call, read on the test's thread until its deadline.
class Watch {
 public:
  Watch(v1::SessionService::Stub& stub, const std::string& session_id, const std::string& token = {}) {
    context_.set_deadline(std::chrono::system_clock::now() + 90s);
    Authorize(context_, token);
    v1::WatchSessionRequest request;
    request.set_session_id(session_id);
    reader_ = stub.WatchSession(&context_, request);
  }
  ~Watch() {
    if (status_) return;
    context_.TryCancel();
    Finish();
  }

  // The first frame whose last_event_seq reaches `seq`; none when the call ends first.
  std::optional<v1::Frame> FrameReaching(std::uint64_t seq) {
    v1::ServerMessage message;
    for (int i = 0; i < kMaxMessages && !status_ && reader_->Read(&message); ++i) {
      if (message.has_frame() && message.frame().last_event_seq() >= seq) return message.frame();
    }
    return std::nullopt;
  }

  // Reads to the end of the call; its status.
  grpc::Status Finish() {
    if (status_) return *status_;
    v1::ServerMessage message;
    for (int i = 0; i < kMaxMessages && reader_->Read(&message); ++i) {
    }
    status_ = reader_->Finish();
    return *status_;
  }

  bool SessionEndedTrailer() const {
    const auto& trailers = context_.GetServerTrailingMetadata();
    return trailers.find("cinevol-session-ended") != trailers.end();
  }

 private:
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::ServerMessage>> reader_;
  std::optional<grpc::Status> status_;
};

v1::SessionEvent CameraEvent(std::uint64_t seq, v1::NamedView view) {
  v1::SessionEvent e;
  e.set_seq(seq);
  e.mutable_camera()->set_view(view);
  return e;
}

v1::SessionEvent ResizeEvent(std::uint64_t seq, std::uint32_t width, std::uint32_t height) {
  v1::SessionEvent e;
  e.set_seq(seq);
  e.mutable_resize()->set_width(width);
  e.mutable_resize()->set_height(height);
  return e;
}

// SendEvents with `events`; the answer in `response`.
grpc::Status SendEvents(v1::SessionService::Stub& stub, const std::string& session_id,
                        const std::vector<v1::SessionEvent>& events, v1::SendEventsResponse* response = nullptr,
                        const std::string& token = {}) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 10s);
  Authorize(context, token);
  v1::SendEventsRequest request;
  request.set_session_id(session_id);
  for (const v1::SessionEvent& e : events) *request.add_events() = e;
  v1::SendEventsResponse ignored;
  return stub.SendEvents(&context, request, response ? response : &ignored);
}

void ExpectStatus(const grpc::Status& status, grpc::StatusCode code, const std::string& text) {
  EXPECT_EQ(status.error_code(), code) << status.error_message();
  EXPECT_NE(status.error_message().find(text), std::string::npos) << status.error_message();
}

TEST(WatchSession, StreamsFramesThatFollowSendEvents) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession());
  auto stub = v1::SessionService::NewStub(client.channel());
  Watch watch(*stub, created.session_id());
  const auto first = watch.FrameReaching(0);
  ASSERT_TRUE(first) << watch.Finish().error_message();
  EXPECT_EQ(first->width(), 96u);

  v1::SendEventsResponse response;
  const grpc::Status sent = SendEvents(*stub, created.session_id(), {CameraEvent(1, v1::LEFT)}, &response);
  ASSERT_TRUE(sent.ok()) << sent.error_message();
  EXPECT_EQ(response.state().last_event_seq(), 1u) << "the state after the batch";
  EXPECT_TRUE(FromTheLeft(response.state().scene().camera())) << "LEFT, resolved to numbers";
  const auto moved = watch.FrameReaching(1);
  ASSERT_TRUE(moved) << watch.Finish().error_message();
  EXPECT_GT(moved->frame_id(), first->frame_id());
}

TEST(WatchSession, ASecondWatchTakesOverAndTheFirstEndsAborted) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession());
  auto stub = v1::SessionService::NewStub(client.channel());
  Watch first(*stub, created.session_id());
  ASSERT_TRUE(first.FrameReaching(0)) << first.Finish().error_message();

  Watch second(*stub, created.session_id());
  ExpectStatus(first.Finish(), grpc::StatusCode::ABORTED, "another stream attached");
  EXPECT_FALSE(first.SessionEndedTrailer()) << "the session lives on";
  // Sequence numbers start again with the attach.
  ASSERT_TRUE(SendEvents(*stub, created.session_id(), {CameraEvent(1, v1::RIGHT)}).ok());
  EXPECT_TRUE(second.FrameReaching(1)) << second.Finish().error_message();
}

TEST(WatchSession, SendEventsChecksTheOwnerAndABadEventLeavesTheSessionStreaming) {
  ScratchDir scratch;
  std::ofstream(scratch / "tokens") << "alice-token alice\nbob-token bob\n";
  ServerProcess server(scratch.path(), {"--auth-tokens", (scratch / "tokens").string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Client alice = server.Connect("alice-token");
  const auto created = alice.CreateSession(SmallSession());
  const std::string& id = created.session_id();
  auto stub = v1::SessionService::NewStub(alice.channel());

  {
    Watch bobs(*stub, id, "bob-token");
    ExpectStatus(bobs.Finish(), grpc::StatusCode::PERMISSION_DENIED, "another user");
  }
  Watch watch(*stub, id, "alice-token");
  ASSERT_TRUE(watch.FrameReaching(0)) << watch.Finish().error_message();
  ExpectStatus(SendEvents(*stub, id, {CameraEvent(1, v1::LEFT)}, nullptr, "bob-token"),
               grpc::StatusCode::PERMISSION_DENIED, "another user");
  ExpectStatus(
      SendEvents(*stub, "0123456789abcdef0123456789abcdef", {CameraEvent(1, v1::LEFT)}, nullptr, "alice-token"),
      grpc::StatusCode::NOT_FOUND, "session_id");

  ExpectStatus(SendEvents(*stub, id, {ResizeEvent(1, 0, 64)}, nullptr, "alice-token"),
               grpc::StatusCode::INVALID_ARGUMENT, "resize");
  // The event before the bad one stays applied; the bad one and those after it do not.
  ExpectStatus(SendEvents(*stub, id, {CameraEvent(2, v1::LEFT), CameraEvent(2, v1::RIGHT), CameraEvent(3, v1::RIGHT)},
                          nullptr, "alice-token"),
               grpc::StatusCode::INVALID_ARGUMENT, "seq must increase");
  v1::SendEventsResponse response;
  ASSERT_TRUE(SendEvents(*stub, id, {}, &response, "alice-token").ok());
  EXPECT_EQ(response.state().last_event_seq(), 2u);
  EXPECT_TRUE(FromTheLeft(response.state().scene().camera())) << "LEFT, resolved to numbers";
  EXPECT_EQ(response.state().viewport().width(), 96u);

  ASSERT_TRUE(SendEvents(*stub, id, {CameraEvent(4, v1::SUPERIOR)}, &response, "alice-token").ok());
  EXPECT_EQ(response.state().last_event_seq(), 4u);
  EXPECT_TRUE(watch.FrameReaching(4)) << "the session still streams: " << watch.Finish().error_message();
}

TEST(WatchSession, SendEventsBoundsItsBatches) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--max-events-per-second", "20"});  // batches: 80 events a second
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession());
  auto stub = v1::SessionService::NewStub(client.channel());

  std::vector<v1::SessionEvent> events;
  for (std::uint64_t seq = 1; seq <= 65; ++seq) events.push_back(CameraEvent(seq, v1::LEFT));
  ExpectStatus(SendEvents(*stub, created.session_id(), events), grpc::StatusCode::INVALID_ARGUMENT, "events");
  events.pop_back();
  v1::SendEventsResponse response;
  ASSERT_TRUE(SendEvents(*stub, created.session_id(), events, &response).ok());
  EXPECT_EQ(response.state().last_event_seq(), 20u) << "the rate's events apply at once, the rest coalesce";
  // Another 64 within 0.6 s pass the batches' rate (16 left, 80 a second).
  for (auto& e : events) e.set_seq(e.seq() + 64);
  ExpectStatus(SendEvents(*stub, created.session_id(), events), grpc::StatusCode::RESOURCE_EXHAUSTED,
               "--max-events-per-second");
}

TEST(WatchSession, GetStatusListsThePresets) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto presets = client.Status().presets();
  EXPECT_NE(std::find(presets.begin(), presets.end(), "ct-bone"), presets.end());
}

TEST(WatchSession, CloseSessionEndsTheWatchWithOkAndTheSessionEndedTrailer) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession());
  auto stub = v1::SessionService::NewStub(client.channel());
  Watch watch(*stub, created.session_id());
  ASSERT_TRUE(watch.FrameReaching(0)) << watch.Finish().error_message();
  client.CloseSession(created.session_id());
  const grpc::Status status = watch.Finish();
  EXPECT_TRUE(status.ok()) << status.error_message();
  EXPECT_TRUE(watch.SessionEndedTrailer());
  ExpectStatus(SendEvents(*stub, created.session_id(), {CameraEvent(1, v1::LEFT)}), grpc::StatusCode::NOT_FOUND,
               "session_id");
}

}  // namespace
}  // namespace cinevol::testing
