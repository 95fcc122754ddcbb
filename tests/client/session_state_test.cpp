// SessionState: the client's copy of what a session is now, from which
// failover creates it again. Each event must change it as the server does.
#include "session_state.h"

#include <gtest/gtest.h>

namespace cinevol {
namespace {

v1::CreateSessionResponse Created() {
  v1::CreateSessionResponse created;
  v1::Scene& scene = *created.mutable_scene();
  scene.mutable_volume()->set_file("head.nrrd");
  scene.mutable_camera()->set_fov_y_deg(30);
  scene.mutable_render()->set_width(96);
  scene.mutable_render()->set_height(64);
  scene.mutable_render()->set_spp(2);
  scene.mutable_render()->set_max_bounces(4);
  scene.mutable_render()->set_seed(7);
  scene.add_lights()->mutable_point();
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

TEST(SessionState, StartsFromTheServersSceneNotThePreset) {
  const SessionState state(Request(), Created());
  EXPECT_TRUE(state.request().has_scene());
  EXPECT_TRUE(state.request().preset().empty());
  EXPECT_FALSE(state.request().scene().has_volume()) << "volume_id says which";
  EXPECT_EQ(state.request().volume_id(), "phantom:head");
  EXPECT_EQ(state.request().scene().render().seed(), 7u);
}

TEST(SessionState, EventsReplaceOrMergeAsTheServerDoes) {
  SessionState state(Request(), Created());
  v1::SessionEvent e;
  e.mutable_camera()->mutable_eye()->set_x(100);
  state.Apply(e);
  EXPECT_EQ(state.request().scene().camera().eye().x(), 100);
  EXPECT_FALSE(state.request().scene().camera().has_fov_y_deg()) << "a camera replaces the camera";

  e.Clear();
  e.mutable_render()->set_spp(8);
  state.Apply(e);
  EXPECT_EQ(state.request().scene().render().spp(), 8u);
  EXPECT_EQ(state.request().scene().render().max_bounces(), 4u) << "unset render fields stay";
  EXPECT_EQ(state.request().scene().render().seed(), 7u);

  e.Clear();
  e.mutable_resize()->set_width(320);
  e.mutable_resize()->set_height(200);
  state.Apply(e);
  EXPECT_EQ(state.request().viewport().width(), 320u);
  EXPECT_EQ(state.request().scene().render().height(), 200u);

  e.Clear();
  e.mutable_stream()->set_jpeg_quality(50);
  state.Apply(e);
  EXPECT_EQ(state.request().stream().jpeg_quality(), 50u);
  EXPECT_EQ(state.request().stream().target_spp(), 16u) << "unset stream fields stay";

  e.Clear();
  e.mutable_lights();  // no lights at all
  state.Apply(e);
  EXPECT_EQ(state.request().scene().lights_size(), 0);

  e.Clear();
  e.mutable_clipping()->add_planes()->mutable_normal()->set_x(1);
  state.Apply(e);
  EXPECT_EQ(state.request().scene().clipping().planes_size(), 1);

  e.Clear();
  e.mutable_pause();
  state.Apply(e);
  EXPECT_TRUE(state.paused());
  e.Clear();
  e.mutable_resume();
  state.Apply(e);
  EXPECT_FALSE(state.paused());
}

}  // namespace
}  // namespace cinevol
