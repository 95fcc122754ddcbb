// ApplyEvent: what each event does to a session's state, the one rule the
// server applies (and every client shows, from the server's answers).
#include "scene/session_state.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "core/error.h"
#include "io/phantom.h"
#include "scene/scene_file.h"

namespace cinevol {
namespace {

const Volume& Head() {
  static const Volume head = [] {
    v1::Phantom spec;
    spec.set_kind(v1::Phantom::HEAD);
    spec.set_size(16);
    return MakePhantom(spec);
  }();
  return head;
}

const SceneContext kHead{Head()};

v1::SessionState Started(const SessionLimits& limits = {}, const SceneContext& context = kHead) {
  v1::CreateSessionRequest request;
  request.set_preset("ct-bone");
  request.mutable_viewport()->set_width(96);
  request.mutable_viewport()->set_height(64);
  request.mutable_stream()->set_target_spp(16);
  return InitialState(request, context, limits);
}

v1::SessionEvent Numbered(std::uint64_t seq) {
  v1::SessionEvent e;
  e.set_seq(seq);
  return e;
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
  EXPECT_EQ(ApplyEvent(state, e, kHead, &limits), unsigned(kCameraChanged));
  EXPECT_EQ(state.scene().camera().eye().x(), 100);
  EXPECT_EQ(state.scene().camera().fov_y_deg(), 30) << "an unset fov takes its default";
  EXPECT_EQ(state.last_event_seq(), 1u);

  e.Clear();
  e.set_seq(2);
  e.mutable_render()->set_spp(8);
  EXPECT_EQ(ApplyEvent(state, e, kHead, &limits), unsigned(kSamplingChanged));
  EXPECT_EQ(state.scene().render().spp(), 8u);
  EXPECT_EQ(state.scene().render().max_bounces(), 4u) << "unset render fields stay";

  e.Clear();
  e.set_seq(3);
  e.mutable_resize()->set_width(320);
  e.mutable_resize()->set_height(200);
  EXPECT_EQ(ApplyEvent(state, e, kHead, &limits), unsigned(kCameraChanged));
  EXPECT_EQ(state.viewport().width(), 320u);
  EXPECT_EQ(state.scene().render().height(), 200u);

  e.Clear();
  e.set_seq(4);
  e.mutable_stream()->set_jpeg_quality(50);
  EXPECT_EQ(ApplyEvent(state, e, kHead, &limits), unsigned(kStreamChanged));
  EXPECT_EQ(state.stream().jpeg_quality(), 50u);
  EXPECT_EQ(state.stream().target_spp(), 16u) << "unset stream fields stay";

  e.Clear();
  e.set_seq(5);
  e.mutable_lights();  // no lights at all
  EXPECT_EQ(ApplyEvent(state, e, kHead, &limits), unsigned(kLightsChanged));
  EXPECT_EQ(state.scene().lights_size(), 0);

  e.Clear();
  e.set_seq(6);
  e.mutable_clipping()->add_planes()->mutable_normal()->set_x(1);
  EXPECT_EQ(ApplyEvent(state, e, kHead, &limits), unsigned(kClippingChanged));
  EXPECT_EQ(state.scene().clipping().planes_size(), 1);

  e.Clear();
  e.set_seq(7);
  e.mutable_pause();
  EXPECT_EQ(ApplyEvent(state, e, kHead, &limits), unsigned(kPauseChanged));
  EXPECT_TRUE(state.paused());
  EXPECT_EQ(ApplyEvent(state, e, kHead, &limits), 0u) << "paused already";
  e.Clear();
  e.set_seq(8);
  e.mutable_resume();
  EXPECT_EQ(ApplyEvent(state, e, kHead, &limits), unsigned(kPauseChanged));
  EXPECT_FALSE(state.paused());
}

// A named view puts its target at the framed distance whatever the lens's
// focal distance: at 8e-13 mm (a fuzzer's input) the target rounded onto the
// eye and the accepted state failed the scene's own check.
TEST(SessionEvents, ANamedViewsTargetIgnoresTheFocalDistance) {
  const SessionLimits limits;
  auto target_distance = [&](float focal_distance_mm) {
    v1::SessionState state = Started(limits);
    v1::SessionEvent e = Numbered(1);
    e.mutable_camera()->set_view(v1::ANTERIOR);
    e.mutable_camera()->set_focal_distance_mm(focal_distance_mm);
    ApplyEvent(state, e, kHead, &limits);
    EXPECT_TRUE(ValidateSceneParts(state.scene()).empty()) << focal_distance_mm;
    EXPECT_EQ(state.scene().camera().focal_distance_mm(), focal_distance_mm) << "the lens keeps its focus";
    const v1::Camera& c = state.scene().camera();
    return std::hypot(c.target().x() - c.eye().x(), c.target().y() - c.eye().y(), c.target().z() - c.eye().z());
  };
  const double framed = target_distance(0.0f);
  EXPECT_GT(framed, 1.0);
  EXPECT_NEAR(target_distance(7.98e-13f), framed, 1e-3 * framed);
  EXPECT_NEAR(target_distance(500.0f), framed, 1e-3 * framed);
}

TEST(SessionEvents, AnEventThatLeavesItsPartAsItWasChangesNothing) {
  const SessionLimits limits;
  v1::SessionState state = Started();
  std::uint64_t seq = 0;
  auto apply = [&](v1::SessionEvent e) {
    e.set_seq(++seq);
    return ApplyEvent(state, e, kHead, &limits);
  };
  v1::SessionEvent camera;
  *camera.mutable_camera() = state.scene().camera();
  EXPECT_EQ(apply(camera), 0u) << "the state's own camera";
  EXPECT_EQ(state.last_event_seq(), seq) << "answered all the same";
  camera.mutable_camera()->mutable_eye()->set_x(camera.camera().eye().x() + 1);
  EXPECT_EQ(apply(camera), unsigned(kCameraChanged));
  EXPECT_EQ(apply(camera), 0u) << "the same move again";

  v1::SessionEvent tf;
  *tf.mutable_transfer_function() = state.scene().transfer_function();
  EXPECT_EQ(apply(tf), 0u);
  v1::SessionEvent resize;
  resize.mutable_resize()->set_width(96);
  resize.mutable_resize()->set_height(64);
  EXPECT_EQ(apply(resize), 0u) << "the size it has";
  resize.mutable_resize()->set_width(97);
  EXPECT_EQ(apply(resize), unsigned(kCameraChanged));
  v1::SessionEvent lights;
  *lights.mutable_lights()->mutable_lights() = state.scene().lights();
  EXPECT_EQ(apply(lights), 0u);
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
    ApplyEvent(state, e, kHead, &limits);
    FAIL() << "accepted";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("event 9: camera"), std::string::npos) << error.what();
  }
  EXPECT_EQ(state.SerializeAsString(), before.SerializeAsString());

  e.Clear();
  e.set_seq(10);
  e.mutable_render()->set_spp(1000);
  EXPECT_THROW(ApplyEvent(state, e, kHead, &limits), OverLimit) << "over --max-frame-spp";
  EXPECT_NO_THROW(ApplyEvent(state, e, kHead, nullptr)) << "no limits: only the scene's own ranges";
}

// A camera event checks the camera and the frame, not the rest: a transfer
// function over this server's point limit (accepted under a larger one)
// does not make every later camera move fail, and costs nothing to re-check.
TEST(SessionEvents, OnlyWhatAnEventTouchesIsChecked) {
  SessionLimits roomy;
  roomy.max_tf_points = 1000;
  v1::SessionState state = Started(roomy);
  v1::TransferFunction& tf = *state.mutable_scene()->mutable_transfer_function();
  const float last = tf.points(tf.points_size() - 1).value();
  for (int i = 1; i <= 300; ++i) tf.add_points()->set_value(last + float(i));
  const SessionLimits tight;
  v1::SessionEvent e;
  e.set_seq(1);
  e.mutable_camera()->set_view(v1::LEFT);
  EXPECT_EQ(ApplyEvent(state, e, kHead, &tight), unsigned(kCameraChanged));
  e.Clear();
  e.set_seq(2);
  *e.mutable_transfer_function() = state.scene().transfer_function();
  EXPECT_THROW(ApplyEvent(state, e, kHead, &tight), OverLimit);
}

TEST(SessionEvents, ARecreatedSessionStartsWhereTheStateIs) {
  v1::SessionState state = Started();
  v1::SessionEvent e;
  e.set_seq(1);
  e.mutable_resize()->set_width(48);
  e.mutable_resize()->set_height(32);
  ApplyEvent(state, e, kHead, nullptr);
  const v1::CreateSessionRequest again = RecreateRequest(state, "head");
  EXPECT_EQ(again.volume_id(), "head");
  EXPECT_EQ(again.viewport().width(), 48u);
  const v1::SessionState recreated = InitialState(again, kHead, {});
  EXPECT_EQ(recreated.scene().SerializeAsString(), state.scene().SerializeAsString());
}

// The state is resolved: clients show it and work nothing out again.
TEST(ResolvedState, TheCameraIsNumbersThePresetPointsAndThePlacementTheVolumes) {
  const v1::SessionState state = Started();
  const v1::Camera& camera = state.scene().camera();
  EXPECT_EQ(camera.view(), v1::NAMED_VIEW_UNSPECIFIED) << "the preset's anterior view, turned into numbers";
  EXPECT_TRUE(camera.has_eye() && camera.has_target() && camera.has_up());
  EXPECT_LT(camera.eye().y(), camera.target().y()) << "anterior: the eye in front of the face (-y in LPS)";
  const v1::TransferFunction& tf = state.scene().transfer_function();
  EXPECT_EQ(tf.preset(), "ct-bone") << "the name stays, for showing";
  EXPECT_GE(tf.points_size(), 2);
  EXPECT_TRUE(tf.has_density_scale() && tf.has_gradient_factor());
  const v1::VolumePlacement& p = state.placement();
  ASSERT_EQ(p.direction_size(), 9);
  EXPECT_EQ(p.dims().x(), 16u);
  EXPECT_FLOAT_EQ(p.spacing_mm().x(), Head().spacing_mm().x);
}

// Bug 2 of issue 56: after a transfer-function edit the server framed a
// named view again while clients kept the eye from creation, so the next
// drag jumped. The camera is numbers from the start and stays.
TEST(ResolvedState, ATransferFunctionEditLeavesTheCameraWhereItWas) {
  v1::SessionState state = Started();
  const std::string camera = state.scene().camera().SerializeAsString();
  v1::SessionEvent e = Numbered(1);
  e.mutable_transfer_function()->set_preset("ct-soft-tissue");  // shows more of the head than bone does
  EXPECT_EQ(ApplyEvent(state, e, kHead, nullptr), unsigned(kTransferFunctionChanged));
  EXPECT_EQ(state.scene().camera().SerializeAsString(), camera);
  EXPECT_EQ(state.scene().transfer_function().preset(), "ct-soft-tissue");
  EXPECT_GE(state.scene().transfer_function().points_size(), 2) << "the preset expanded on the server";
}

// Bug 1 of issue 56: the desktop viewer expanded presets itself with a 1 mm
// voxel, 10x too dense on 0.1 mm data. A preset is expanded once, on the
// server, with the volume's spacing.
TEST(ResolvedState, APresetIsExpandedWithTheVolumesSpacing) {
  auto density = [](float spacing) {
    v1::Phantom spec;
    spec.set_kind(v1::Phantom::SPHERE);
    spec.set_size(16);
    spec.set_spacing(spacing);
    const Volume sphere = MakePhantom(spec);
    v1::CreateSessionRequest request;
    request.set_preset("auto");  // extinction per voxel
    request.mutable_viewport()->set_width(32);
    request.mutable_viewport()->set_height(32);
    v1::SessionState state = InitialState(request, SceneContext{sphere}, {});
    v1::SessionEvent e = Numbered(1);
    e.mutable_transfer_function()->set_preset("auto");
    ApplyEvent(state, e, SceneContext{sphere}, nullptr);
    return state.scene().transfer_function().density_scale();
  };
  const float coarse = density(1.0f), fine = density(0.1f);
  ASSERT_GT(coarse, 0.0f);
  EXPECT_NEAR(fine / coarse, 10.0f, 0.01f);
}

// A view button sends the view with the eye and target it turns about.
// A DICOM SEG's recommended colours become the labels' styles of a scene
// that styles none; a scene's own styles stay as they are.
TEST(ResolvedState, ASegsRecommendedColoursAreTheLabelStyles) {
  LabelVolume seg;
  seg.dims = Head().dims();
  seg.labels.assign(std::size_t(seg.dims.x) * seg.dims.y * seg.dims.z, 0);
  seg.labels[seg.labels.size() / 2] = 3;
  seg.names = {{3, "liver"}};
  seg.colors = {{3, Vec3f{0.8f, 0.2f, 0.1f}}};
  seg.voxels = {{3, 1}};
  const SceneContext context{Head(), &seg};
  const v1::SessionState state = Started({}, context);
  ASSERT_EQ(state.scene().labels().styles_size(), 1);
  const v1::LabelStyle& style = state.scene().labels().styles(0);
  EXPECT_EQ(style.value(), 3u);
  EXPECT_FLOAT_EQ(style.color().r(), 0.8f);
  EXPECT_FLOAT_EQ(style.color().b(), 0.1f);

  v1::CreateSessionRequest request;
  request.mutable_viewport()->set_width(32);
  request.mutable_viewport()->set_height(32);
  request.mutable_scene()->mutable_labels()->add_styles()->set_value(3);  // the reader's own: no colour
  const v1::SessionState own = InitialState(request, context, {});
  ASSERT_EQ(own.scene().labels().styles_size(), 1);
  EXPECT_FALSE(own.scene().labels().styles(0).has_color());
}

TEST(ResolvedState, ANamedViewTurnsAboutTheTargetAtItsDistance) {
  v1::SessionState state = Started();
  v1::SessionEvent e = Numbered(1);
  v1::Camera& c = *e.mutable_camera();
  c.set_view(v1::LEFT);
  c.mutable_eye()->set_y(-200);
  c.mutable_target()->set_x(5);
  ASSERT_EQ(ApplyEvent(state, e, kHead, nullptr), unsigned(kCameraChanged));
  const v1::Camera& turned = state.scene().camera();
  EXPECT_EQ(turned.view(), v1::NAMED_VIEW_UNSPECIFIED);
  EXPECT_FLOAT_EQ(turned.target().x(), 5.0f);
  const float dx = turned.eye().x() - 5.0f, dy = turned.eye().y(), dz = turned.eye().z();
  EXPECT_NEAR(std::sqrt(dx * dx + dy * dy + dz * dz), std::sqrt(25.0f + 200.0f * 200.0f), 1e-2f);
  EXPECT_NEAR(dx, std::sqrt(25.0f + 200.0f * 200.0f), 1e-2f) << "the patient's left is +x in LPS";
  EXPECT_NEAR(turned.up().z(), 1.0f, 1e-6f) << "the head up";

  // Without an eye and target, about the current camera's: an event never
  // frames (that reads the volume on the thread that read the event).
  e = Numbered(2);
  e.mutable_camera()->set_view(v1::SUPERIOR);
  ApplyEvent(state, e, kHead, nullptr);
  const v1::Camera& above = state.scene().camera();
  EXPECT_EQ(above.view(), v1::NAMED_VIEW_UNSPECIFIED);
  EXPECT_FLOAT_EQ(above.target().x(), 5.0f);
  EXPECT_NEAR(above.eye().z() - above.target().z(), std::sqrt(25.0f + 200.0f * 200.0f), 1e-2f) << "from above";
}

// Every rule of a session's scene is here: measurements, pointers, label
// styles without a segmentation, coalescing.
TEST(SessionRules, MeasurementsAreCheckedAndSharedBesideTheQueue) {
  v1::SessionState state = Started();
  v1::SessionEvent e = Numbered(5);
  v1::Measurement* m = e.mutable_measurements()->add_measurements();
  m->set_name("gap");
  m->add_points()->set_x(1);
  m->add_points()->set_x(2);
  EXPECT_EQ(ApplyEvent(state, e, kHead, nullptr), unsigned(kMeasurementsChanged));
  EXPECT_EQ(state.scene().measurements_size(), 1);
  EXPECT_EQ(state.last_event_seq(), 0u) << "measurements skip the event queue";
  m->clear_points();
  EXPECT_THROW(ApplyEvent(state, e, kHead, nullptr), InputError) << "a measurement of no points";
  EXPECT_EQ(state.scene().measurements_size(), 1);
}

TEST(SessionRules, PointersAreListedByWhoAndHiddenOnesGo) {
  v1::SessionState state = Started();
  v1::Pointer p;
  p.set_x(0.5f);
  p.set_y(0.25f);
  EXPECT_EQ(ApplyPointer(state, "zoe", p), unsigned(kPointersChanged));
  EXPECT_EQ(ApplyPointer(state, "ada", p), unsigned(kPointersChanged));
  EXPECT_EQ(ApplyPointer(state, "ada", p), 0u) << "not moved";
  ASSERT_EQ(state.pointers_size(), 2);
  EXPECT_EQ(state.pointers(0).who(), "ada");
  p.set_x(1.5f);
  EXPECT_THROW(ApplyPointer(state, "ada", p), InputError);
  p.set_x(0.5f);
  p.set_hidden(true);
  EXPECT_EQ(ApplyPointer(state, "zoe", p), unsigned(kPointersChanged));
  EXPECT_EQ(HidePointer(state, "ada"), unsigned(kPointersChanged));
  EXPECT_EQ(HidePointer(state, "ada"), 0u);
  EXPECT_EQ(state.pointers_size(), 0);
}

TEST(SessionRules, LabelStylesNeedTheSegmentationTheSessionBeganWith) {
  v1::SessionState state = Started();
  v1::SessionEvent e = Numbered(1);
  e.mutable_labels()->add_styles()->set_value(3);
  try {
    ApplyEvent(state, e, SceneContext{Head(), nullptr, "head"}, nullptr);
    FAIL() << "accepted";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("event 1: labels: volume 'head' had no segmentation"),
              std::string::npos)
        << error.what();
  }
  e.mutable_labels()->clear_styles();
  e.mutable_labels()->set_remove_table(true);
  EXPECT_EQ(ApplyEvent(state, e, kHead, nullptr), unsigned(kLabelsChanged)) << "table removal needs none";
}

TEST(SessionRules, WaitingEventsKeepEachKindsLatestAndMergeSettings) {
  std::map<int, v1::SessionEvent> waiting;
  v1::SessionEvent e = Numbered(1);
  e.mutable_render()->set_spp(4);
  CoalesceEvent(waiting, e);
  e = Numbered(2);
  e.mutable_render()->set_max_bounces(2);
  CoalesceEvent(waiting, e);
  e = Numbered(3);
  e.mutable_camera()->mutable_eye()->set_x(1);
  CoalesceEvent(waiting, e);
  e = Numbered(4);
  e.mutable_camera()->mutable_eye()->set_x(2);
  CoalesceEvent(waiting, e);
  ASSERT_EQ(waiting.size(), 2u);
  const v1::SessionEvent& render = waiting.at(v1::SessionEvent::kRender);
  EXPECT_EQ(render.render().spp(), 4u);
  EXPECT_EQ(render.render().max_bounces(), 2u);
  EXPECT_EQ(render.seq(), 2u);
  EXPECT_EQ(waiting.at(v1::SessionEvent::kCamera).camera().eye().x(), 2.0f);
}

}  // namespace
}  // namespace cinevol
