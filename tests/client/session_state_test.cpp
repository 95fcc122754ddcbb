// SessionState: the client's record of a session for failover: the server's
// last state and the events it has not answered yet.
#include "session_state.h"

#include <gtest/gtest.h>

namespace cinevol {
namespace {

v1::CreateSessionResponse Created() {
  v1::CreateSessionResponse created;
  v1::Scene& scene = *created.mutable_scene();
  scene.mutable_volume()->set_file("head.nrrd");
  scene.mutable_render()->set_width(96);
  scene.mutable_render()->set_height(64);
  scene.mutable_render()->set_seed(7);
  return created;
}

v1::CreateSessionRequest Request() {
  v1::CreateSessionRequest request;
  request.set_volume_id("phantom:head");
  request.set_preset("ct-bone");
  request.mutable_viewport()->set_width(96);
  request.mutable_viewport()->set_height(64);
  request.mutable_stream()->set_target_spp(16);
  return request;
}

v1::SessionEvent Event(std::uint64_t seq) {
  v1::SessionEvent e;
  e.set_seq(seq);
  e.mutable_camera()->mutable_eye()->set_x(float(seq));
  return e;
}

TEST(SessionState, StartsFromTheServersSceneNotThePreset) {
  const SessionState state(Request(), Created());
  EXPECT_TRUE(state.request().has_scene());
  EXPECT_TRUE(state.request().preset().empty());
  EXPECT_FALSE(state.request().scene().has_volume()) << "volume_id says which";
  EXPECT_EQ(state.request().volume_id(), "phantom:head");
  EXPECT_EQ(state.request().scene().render().seed(), 7u);
  EXPECT_TRUE(state.Unanswered().empty());
}

TEST(SessionState, TheServersStateReplacesItsOwnAndAnswersEventsUpToItsSeq) {
  SessionState state(Request(), Created());
  for (std::uint64_t seq = 1; seq <= 3; ++seq) state.Sent(Event(seq));
  v1::SessionState server;
  server.mutable_scene()->mutable_render()->set_width(320);
  server.mutable_scene()->mutable_camera()->mutable_eye()->set_x(2);
  server.mutable_viewport()->set_width(320);
  server.mutable_stream()->set_jpeg_quality(50);
  server.set_last_event_seq(2);
  state.Adopt(server);
  EXPECT_EQ(state.request().scene().camera().eye().x(), 2);
  EXPECT_EQ(state.request().viewport().width(), 320u);
  EXPECT_EQ(state.request().stream().jpeg_quality(), 50u);
  EXPECT_EQ(state.request().volume_id(), "phantom:head");
  const std::vector<v1::SessionEvent> left = state.Unanswered();
  ASSERT_EQ(left.size(), 1u) << "only event 3 is newer than the state";
  EXPECT_EQ(left[0].seq(), 3u);

  state.Recreated();
  EXPECT_TRUE(state.Unanswered().empty());
}

TEST(SessionState, APausedSessionIsPausedAgainBeforeItsUnansweredEvents) {
  SessionState state(Request(), Created());
  v1::SessionState server;
  server.set_paused(true);
  state.Adopt(server);
  state.Sent(Event(1));
  const std::vector<v1::SessionEvent> replay = state.Unanswered();
  ASSERT_EQ(replay.size(), 2u);
  EXPECT_TRUE(replay[0].has_pause());
  EXPECT_TRUE(replay[1].has_camera());
}

TEST(SessionState, ANewStreamOnTheSameSessionLeavesNothingToReplay) {
  SessionState state(Request(), Created());
  state.Sent(Event(1));
  state.Reattached();
  EXPECT_TRUE(state.Unanswered().empty());
}

// A server that never answers (one older than ServerMessage.state) must not
// make the client keep every event it sent: one per kind, render settings merged.
TEST(SessionState, UnansweredEventsAreKeptOnePerKind) {
  SessionState state(Request(), Created());
  for (std::uint64_t seq = 1; seq <= 10000; ++seq) state.Sent(Event(seq));
  v1::SessionEvent spp;
  spp.set_seq(10001);
  spp.mutable_render()->set_spp(8);
  state.Sent(spp);
  v1::SessionEvent bounces;
  bounces.set_seq(10002);
  bounces.mutable_render()->set_max_bounces(2);
  state.Sent(bounces);
  const std::vector<v1::SessionEvent> replay = state.Unanswered();
  ASSERT_EQ(replay.size(), 2u);
  EXPECT_EQ(replay[0].camera().eye().x(), 10000.0f) << "the latest camera";
  EXPECT_EQ(replay[1].render().spp(), 8u);
  EXPECT_EQ(replay[1].render().max_bounces(), 2u);
}

}  // namespace
}  // namespace cinevol
