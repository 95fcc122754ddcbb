// ApplyEvent: what each event does to a session's state, the one rule the
// server applies (and every client shows, from the server's answers).
#include "scene/session_state.h"

#include <gtest/gtest.h>

#include "core/error.h"
#include "io/phantom.h"

namespace cinevol {
namespace {

Volume Head() {
  v1::Phantom head;
  head.set_kind(v1::Phantom::HEAD);
  head.set_size(16);
  return MakePhantom(head);
}

v1::SessionState Started(const SessionLimits& limits = {}) {
  v1::CreateSessionRequest request;
  request.set_preset("ct-bone");
  request.mutable_viewport()->set_width(96);
  request.mutable_viewport()->set_height(64);
  request.mutable_stream()->set_target_spp(16);
  return InitialState(request, Head(), limits);
}

TEST(SessionEvents, EachEventReplacesOrMergesItsPartAndSaysWhatChanged) {
  const SessionLimits limits;
  v1::SessionState state = Started();
  EXPECT_EQ(state.scene().render().width(), 96u);
  EXPECT_GT(state.scene().lights_size(), 0) << "the preset's lights";

  v1::SessionEvent e;
  e.set_seq(1);
  e.mutable_camera()->mutable_eye()->set_x(100);
  e.mutable_camera()->mutable_target()->set_y(1);
  EXPECT_EQ(ApplyEvent(state, e, &limits), unsigned(kCameraChanged));
  EXPECT_EQ(state.scene().camera().eye().x(), 100);
  EXPECT_EQ(state.scene().camera().fov_y_deg(), 30) << "an unset fov takes its default";
  EXPECT_EQ(state.last_event_seq(), 1u);

  e.Clear();
  e.set_seq(2);
  e.mutable_render()->set_spp(8);
  EXPECT_EQ(ApplyEvent(state, e, &limits), unsigned(kSamplingChanged));
  EXPECT_EQ(state.scene().render().spp(), 8u);
  EXPECT_EQ(state.scene().render().max_bounces(), 4u) << "unset render fields stay";

  e.Clear();
  e.set_seq(3);
  e.mutable_resize()->set_width(320);
  e.mutable_resize()->set_height(200);
  EXPECT_EQ(ApplyEvent(state, e, &limits), unsigned(kCameraChanged));
  EXPECT_EQ(state.viewport().width(), 320u);
  EXPECT_EQ(state.scene().render().height(), 200u);

  e.Clear();
  e.set_seq(4);
  e.mutable_stream()->set_jpeg_quality(50);
  EXPECT_EQ(ApplyEvent(state, e, &limits), unsigned(kStreamChanged));
  EXPECT_EQ(state.stream().jpeg_quality(), 50u);
  EXPECT_EQ(state.stream().target_spp(), 16u) << "unset stream fields stay";

  e.Clear();
  e.set_seq(5);
  e.mutable_lights();  // no lights at all
  EXPECT_EQ(ApplyEvent(state, e, &limits), unsigned(kLightsChanged));
  EXPECT_EQ(state.scene().lights_size(), 0);

  e.Clear();
  e.set_seq(6);
  e.mutable_clipping()->add_planes()->mutable_normal()->set_x(1);
  EXPECT_EQ(ApplyEvent(state, e, &limits), unsigned(kClippingChanged));
  EXPECT_EQ(state.scene().clipping().planes_size(), 1);

  e.Clear();
  e.set_seq(7);
  e.mutable_pause();
  EXPECT_EQ(ApplyEvent(state, e, &limits), unsigned(kPauseChanged));
  EXPECT_TRUE(state.paused());
  EXPECT_EQ(ApplyEvent(state, e, &limits), 0u) << "paused already";
  e.Clear();
  e.set_seq(8);
  e.mutable_resume();
  EXPECT_EQ(ApplyEvent(state, e, &limits), unsigned(kPauseChanged));
  EXPECT_FALSE(state.paused());
}

TEST(SessionEvents, ABadEventNamesItsFieldAndLeavesTheStateAsItWas) {
  const SessionLimits limits;
  v1::SessionState state = Started();
  const v1::SessionState before = state;
  v1::SessionEvent e;
  e.set_seq(9);
  e.mutable_camera()->mutable_eye()->set_x(1);  // eye == target
  e.mutable_camera()->mutable_target()->set_x(1);
  try {
    ApplyEvent(state, e, &limits);
    FAIL() << "accepted";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("event 9: camera"), std::string::npos) << error.what();
  }
  EXPECT_EQ(state.SerializeAsString(), before.SerializeAsString());

  e.Clear();
  e.set_seq(10);
  e.mutable_render()->set_spp(1000);
  EXPECT_THROW(ApplyEvent(state, e, &limits), OverLimit) << "over --max-frame-spp";
  EXPECT_NO_THROW(ApplyEvent(state, e, nullptr)) << "no limits: only the scene's own ranges";
}

// A camera event checks the camera and the frame, not the rest: a transfer
// function over this server's point limit (accepted under a larger one)
// does not make every later camera move fail, and costs nothing to re-check.
TEST(SessionEvents, OnlyWhatAnEventTouchesIsChecked) {
  SessionLimits roomy;
  roomy.max_tf_points = 1000;
  v1::SessionState state = Started(roomy);
  for (int i = 0; i < 300; ++i) {
    v1::TransferFunctionPoint* p = state.mutable_scene()->mutable_transfer_function()->add_points();
    p->set_value(2000.0f + float(i));
  }
  const SessionLimits tight;
  v1::SessionEvent e;
  e.set_seq(1);
  e.mutable_camera()->set_view(v1::LEFT);
  EXPECT_EQ(ApplyEvent(state, e, &tight), unsigned(kCameraChanged));
  e.Clear();
  e.set_seq(2);
  *e.mutable_transfer_function() = state.scene().transfer_function();
  EXPECT_THROW(ApplyEvent(state, e, &tight), OverLimit);
}

TEST(SessionEvents, ARecreatedSessionStartsWhereTheStateIs) {
  v1::SessionState state = Started();
  v1::SessionEvent e;
  e.set_seq(1);
  e.mutable_resize()->set_width(48);
  e.mutable_resize()->set_height(32);
  ApplyEvent(state, e, nullptr);
  const v1::CreateSessionRequest again = RecreateRequest(state, "head");
  EXPECT_EQ(again.volume_id(), "head");
  EXPECT_EQ(again.viewport().width(), 48u);
  const v1::SessionState recreated = InitialState(again, Head(), {});
  EXPECT_EQ(recreated.scene().SerializeAsString(), state.scene().SerializeAsString());
}

}  // namespace
}  // namespace cinevol
