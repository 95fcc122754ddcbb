// What the viewer shows and sends (viewer/shown_session.h): the server's
// state, with this viewer's unanswered edits over it; a preset or a named
// view goes for the server to work out, never worked out here.
#include "viewer/shown_session.h"

#include <gtest/gtest.h>

#include "viewer/second_volume.h"

#include <map>
#include <vector>

namespace cinevol::viewer {
namespace {

// Where the edits go: a record, with deliveries the test decides.
class RecordingSink : public EventSink {
 public:
  bool drives = true;
  std::vector<v1::SessionEvent> posted;
  std::map<std::uint64_t, Delivery> deliveries;  // by ticket; absent: waiting

  bool Drives() const override { return drives; }
  std::uint64_t Post(v1::SessionEvent event) override {
    posted.push_back(std::move(event));
    return posted.size();  // the ticket: 1, 2, ...
  }
  Delivery DeliveryOf(std::uint64_t ticket) const override {
    const auto it = deliveries.find(ticket);
    return it == deliveries.end() ? Delivery{} : it->second;
  }
  // The last event posted went out as `seq`.
  void Sent(std::uint64_t seq) { deliveries[posted.size()] = {Delivery::kSent, seq}; }
};

v1::TransferFunction Points(std::initializer_list<std::pair<float, float>> points, const std::string& preset = "") {
  v1::TransferFunction tf;
  tf.set_preset(preset);
  for (auto [value, opacity] : points) {
    v1::TransferFunctionPoint& p = *tf.add_points();
    p.set_value(value);
    p.set_opacity(opacity);
  }
  return tf;
}

// A resolved state, as the server sends it: numbers, points, where the volume lies.
v1::SessionState Resolved(std::uint64_t seq) {
  v1::SessionState state;
  *state.mutable_scene()->mutable_camera() = ToProto(ViewCamera{{0, -500, 0}, {0, 0, 0}, {0, 0, 1}, 30});
  *state.mutable_scene()->mutable_transfer_function() = Points({{-1000, 0}, {300, 0.1f}, {2000, 0.9f}}, "ct-soft-tissue");
  state.mutable_scene()->mutable_render()->set_spp(2);
  state.mutable_scene()->mutable_render()->set_max_bounces(4);
  state.mutable_stream()->set_jpeg_quality(80);
  state.set_last_event_seq(seq);
  return state;
}

// Bug 1 of issue 56: the viewer expanded presets itself, for a 1 mm voxel
// (ten times too dense on a 0.1 mm micro-CT). It now sends the preset's
// name alone; the server fits it to the volume's values and spacing, and the
// points shown are the server's.
TEST(ShownSession, ChoosingAPresetSendsItsNameForTheServerToFitNotPoints) {
  RecordingSink sink;
  ShownSession session(sink);
  session.Start(Resolved(0));
  session.ChoosePreset("ct-bone");
  ASSERT_EQ(sink.posted.size(), 1u);
  const v1::SessionEvent& sent = sink.posted.back();
  ASSERT_TRUE(sent.has_transfer_function());
  EXPECT_EQ(sent.transfer_function().preset(), "ct-bone");
  EXPECT_EQ(sent.transfer_function().points_size(), 0) << "the viewer expanded the preset itself";
  EXPECT_TRUE(session.Resolving());
  EXPECT_EQ(session.ResolvingPreset(), "ct-bone");
  EXPECT_EQ(session.scene().transfer_function().preset(), "ct-soft-tissue") << "no points of its own meanwhile";
  sink.Sent(7);
  v1::SessionState fitted = Resolved(7);  // fitted to a 0.1 mm micro-CT: what the server says, shown as it says
  *fitted.mutable_scene()->mutable_transfer_function() = Points({{150, 0}, {400, 0.4f}, {3000, 1}}, "ct-bone");
  session.Adopt(fitted);
  EXPECT_FALSE(session.Resolving());
  ASSERT_EQ(session.scene().transfer_function().points_size(), 3);
  EXPECT_FLOAT_EQ(session.scene().transfer_function().points(1).value(), 400);
  EXPECT_EQ(session.scene().transfer_function().preset(), "ct-bone");
}

TEST(ShownSession, ANamedViewGoesAsTheViewAboutTheCurrentTargetAndShowsTheServersNumbers) {
  RecordingSink sink;
  ShownSession session(sink);
  v1::SessionState first = Resolved(0);
  *first.mutable_scene()->mutable_camera() = ToProto(ViewCamera{{10, -290, 20}, {10, 10, 20}, {0, 0, 1}, 30});
  session.Start(first);
  session.TurnTo(v1::LEFT);
  ASSERT_EQ(sink.posted.size(), 1u);
  const v1::Camera& asked = sink.posted.back().camera();
  EXPECT_EQ(asked.view(), v1::LEFT);
  EXPECT_FLOAT_EQ(asked.target().y(), 10) << "the target to turn about";
  EXPECT_FLOAT_EQ(asked.eye().y(), -290) << "the eye: how far from it";
  EXPECT_TRUE(session.Resolving());
  EXPECT_DOUBLE_EQ(session.camera().eye.y, -290) << "the camera shown stays until the server's numbers come";
  sink.Sent(3);
  v1::SessionState turned = Resolved(3);
  *turned.mutable_scene()->mutable_camera() = ToProto(ViewCamera{{310, 10, 20}, {10, 10, 20}, {0, 0, 1}, 30});
  session.Adopt(turned);
  EXPECT_FALSE(session.Resolving());
  EXPECT_DOUBLE_EQ(session.camera().eye.x, 310);
}

TEST(ShownSession, ADragShowsAtOnceGoesOncePerFlushAndHoldsUntilAnswered) {
  RecordingSink sink;
  ShownSession session(sink);
  session.Start(Resolved(0));
  ViewCamera c = session.camera();
  Orbit(c, 10, 0);
  session.SetCamera(c);
  Orbit(c, 10, 0);
  session.SetCamera(c);
  EXPECT_TRUE(sink.posted.empty()) << "the camera waits for the frame's flush";
  EXPECT_TRUE(session.camera_waiting());
  EXPECT_NEAR(session.camera().eye.x, c.eye.x, 1e-4) << "shown at once: the next drag goes on from it";
  EXPECT_TRUE(session.Flush());
  EXPECT_FALSE(session.Flush()) << "once a frame";
  ASSERT_EQ(sink.posted.size(), 1u);
  sink.Sent(5);
  session.Adopt(Resolved(4));  // a state from before the drag: the drag still shows
  EXPECT_NEAR(session.camera().eye.x, c.eye.x, 1e-4);
  v1::SessionState answered = Resolved(5);
  *answered.mutable_scene()->mutable_camera() = sink.posted.back().camera();
  answered.mutable_scene()->mutable_camera()->mutable_eye()->set_z(1);  // as the server keeps it
  session.Adopt(answered);
  EXPECT_FALSE(session.Pending());
  EXPECT_NEAR(session.camera().eye.z, 1, 1e-6) << "answered: the server's state shows";
}

TEST(ShownSession, WhileAnotherDrivesNothingGoesAndTheSessionShowsAsTheServerHasIt) {
  RecordingSink sink;
  sink.drives = false;
  ShownSession session(sink);
  session.Start(Resolved(0));
  session.ChoosePreset("ct-bone");
  session.SetCamera({{1, 2, 3}, {0, 0, 0}, {0, 0, 1}, 30});
  session.SetClipping(v1::Clipping{});
  EXPECT_FALSE(session.Flush());
  EXPECT_TRUE(sink.posted.empty());
  EXPECT_FALSE(session.Pending());
  v1::SessionState moved = Resolved(9);
  *moved.mutable_scene()->mutable_camera() = ToProto(ViewCamera{{0, 0, 700}, {0, 0, 0}, {0, 1, 0}, 30});
  session.Adopt(moved);
  EXPECT_DOUBLE_EQ(session.camera().eye.z, 700) << "the presenter's camera";
}

TEST(ShownSession, AnEditThatCannotReachTheServerGivesWayToItsState) {
  RecordingSink sink;
  ShownSession session(sink);
  session.Start(Resolved(0));
  session.SetTransferFunction(Points({{0, 0}, {100, 1}}));
  EXPECT_EQ(session.scene().transfer_function().points_size(), 2);
  sink.deliveries[1] = {Delivery::kDropped, 0};  // its stream ended under it
  session.Settle();
  EXPECT_EQ(session.scene().transfer_function().points_size(), 3) << "the server's points";
}

TEST(ShownSession, MeasurementsAreAnsweredWhenTheStateHoldsThem) {
  RecordingSink sink;
  ShownSession session(sink);
  session.Start(Resolved(4));
  v1::Measurement m;
  m.set_name("distance 1");
  *m.add_points() = ToProto(Vec3d{0, 0, 0});
  *m.add_points() = ToProto(Vec3d{0, 42.5, 0});
  session.SetMeasurements({m});
  EXPECT_EQ(session.scene().measurements_size(), 1);
  sink.Sent(5);  // the stream numbers it; no state counts it
  session.Adopt(Resolved(4));
  EXPECT_EQ(session.scene().measurements_size(), 1) << "not held yet: still shown as sent";
  v1::SessionState held = Resolved(4);
  *held.mutable_scene()->add_measurements() = m;
  session.Adopt(held);
  EXPECT_FALSE(session.Pending());
  session.SetMeasurements({});  // the last one deleted: an empty list goes
  ASSERT_TRUE(sink.posted.back().has_measurements());
  EXPECT_EQ(sink.posted.back().measurements().measurements_size(), 0);
  EXPECT_EQ(session.scene().measurements_size(), 0);
}

TEST(ShownSession, RenderAndStreamEditsChangeTheFieldsTheySetAsTheServerMerges) {
  RecordingSink sink;
  ShownSession session(sink);
  session.Start(Resolved(0));
  v1::RenderSettings render;
  render.set_spp(8);
  session.SetRender(render);
  EXPECT_EQ(session.scene().render().spp(), 8u);
  EXPECT_EQ(session.scene().render().max_bounces(), 4u) << "bounces as the server has them";
  v1::SessionEvent quality;
  quality.mutable_stream()->set_target_spp(64);
  session.Send(quality);
  v1::SessionEvent denoiser;
  denoiser.mutable_stream()->set_denoiser(v1::DENOISER_SVGF);
  session.Send(denoiser);
  EXPECT_EQ(session.state().stream().target_spp(), 64u) << "a script's second stream line kept the first's field";
  EXPECT_EQ(session.state().stream().denoiser(), v1::DENOISER_SVGF);
  EXPECT_EQ(session.state().stream().jpeg_quality(), 80u);
}

// Issue 59: the Time panel's slider shows the phase chosen while it goes
// (a drag does not jump back to the server's phase a round trip old), then
// the server's time once a state answers it; a script's time line is the
// same edit.
TEST(ShownSession, ATimeEditShowsAtOnceAndGivesWayToTheServersTime) {
  RecordingSink sink;
  ShownSession session(sink);
  session.Start(Resolved(0));
  v1::Time time;
  time.set_phase(3);
  session.SetTime(time);
  ASSERT_EQ(sink.posted.size(), 1u);
  EXPECT_EQ(sink.posted.back().time().phase(), 3u);
  EXPECT_EQ(session.scene().time().phase(), 3u) << "shown at once";
  sink.Sent(1);
  session.Adopt(Resolved(0));  // a state from before it
  EXPECT_EQ(session.scene().time().phase(), 3u);
  v1::SessionState answered = Resolved(1);
  answered.mutable_scene()->mutable_time()->set_phase(3);
  answered.mutable_scene()->mutable_time()->set_playing(true);  // another client pressed Play meanwhile
  session.Adopt(answered);
  EXPECT_FALSE(session.Pending());
  EXPECT_TRUE(session.scene().time().playing()) << "answered: the server's time shows";

  v1::SessionEvent line;  // {"at": 1, "time": {"phase": 1}}
  line.mutable_time()->set_phase(1);
  session.Send(line);
  EXPECT_EQ(session.scene().time().phase(), 1u);
  EXPECT_FALSE(session.scene().time().playing());
  sink.deliveries[2] = {Delivery::kDropped, 0};  // refused: a phase past the last, say
  session.Settle();
  EXPECT_EQ(session.scene().time().phase(), 3u) << "the server's phase stands";
}

// Issue 59: the Second volume panel's edit (a colour map, an opacity, the
// glow turned off) shows at once, then the server's fusion once a state
// answers it; a refused one gives way to the server's. A script's fusion
// line removing the second volume shows without it.
TEST(ShownSession, AFusionEditShowsAtOnceAndGivesWayToTheServersFusion) {
  RecordingSink sink;
  ShownSession session(sink);
  v1::VolumeInfo pet;
  pet.set_id("pet");
  pet.set_min_value(0), pet.set_max_value(1000);
  v1::SessionState first = Resolved(0);
  *first.mutable_scene()->mutable_fusion() = FusedStart(pet, true);
  session.Start(first);
  v1::Fusion fusion = session.scene().fusion();
  fusion.mutable_overlay()->set_color_map(v1::RAINBOW);
  fusion.mutable_overlay()->set_opacity(0.9f);
  SetGlow(fusion, false, pet);
  session.SetFusion(fusion);
  ASSERT_EQ(sink.posted.size(), 1u);
  EXPECT_EQ(sink.posted.back().fusion().volume_id(), "pet") << "the event names the session's second volume";
  EXPECT_EQ(session.scene().fusion().overlay().color_map(), v1::RAINBOW) << "shown at once";
  EXPECT_FALSE(Glows(session.scene().fusion()));
  sink.Sent(1);
  session.Adopt(first);  // a state from before it
  EXPECT_EQ(session.scene().fusion().overlay().opacity(), 0.9f);
  v1::SessionState answered = Resolved(1);
  *answered.mutable_scene()->mutable_fusion() = fusion;
  answered.mutable_scene()->mutable_fusion()->mutable_overlay()->set_opacity(0.7f);  // another client's since
  session.Adopt(answered);
  EXPECT_FALSE(session.Pending());
  EXPECT_EQ(session.scene().fusion().overlay().opacity(), 0.7f) << "answered: the server's fusion shows";

  fusion.mutable_overlay()->set_color_map(v1::GRAY);
  session.SetFusion(fusion);
  sink.deliveries[2] = {Delivery::kDropped, 0};  // refused: an opacity past 1, say
  session.Settle();
  EXPECT_EQ(session.scene().fusion().overlay().color_map(), v1::RAINBOW) << "the server's colour map stands";

  v1::SessionEvent removal;  // {"at": 1, "fusion": {}}
  removal.mutable_fusion();
  session.Send(removal);
  EXPECT_FALSE(session.scene().has_fusion());
}

// The viewer's --fuse and glow are the page's (web/src/fusion_panel.ts,
// fusedStart and glowOf): HOT at half opacity, glowing warm over the top
// 70% of the range, or from SUVbw 2.5 to 10 where the volume has SUVbw.
TEST(ShownSession, AFusedStartGlowsAsThePagesDoes) {
  v1::VolumeInfo ct_like;
  ct_like.set_id("hot");
  ct_like.set_min_value(-1000), ct_like.set_max_value(1000);
  const v1::Fusion fusion = FusedStart(ct_like, true);
  EXPECT_EQ(fusion.volume_id(), "hot");
  EXPECT_TRUE(fusion.align_by_patient());
  EXPECT_FALSE(fusion.suv());
  EXPECT_EQ(fusion.overlay().color_map(), v1::HOT);
  EXPECT_EQ(fusion.overlay().opacity(), 0.5f);
  EXPECT_FALSE(fusion.overlay().has_window()) << "the overlay spans the volume's range";
  const v1::TransferFunction& glow = fusion.transfer_function();
  ASSERT_EQ(glow.points_size(), 2);
  EXPECT_FLOAT_EQ(glow.points(0).value(), -400);
  EXPECT_EQ(glow.points(0).opacity(), 0);
  EXPECT_EQ(glow.points(0).emission().r(), 0);
  EXPECT_FLOAT_EQ(glow.points(1).value(), 1000);
  EXPECT_FLOAT_EQ(glow.points(1).opacity(), 0.4f);
  EXPECT_FLOAT_EQ(glow.points(1).emission().r(), 6);
  EXPECT_FLOAT_EQ(glow.points(1).emission().g(), 2.4f);
  EXPECT_FLOAT_EQ(glow.points(1).diffuse().g(), 0.4f);
  EXPECT_EQ(glow.density_scale(), 1);

  v1::VolumeInfo pet = ct_like;
  pet.set_suv_factor(1e-3);
  const v1::Fusion suv = FusedStart(pet, false);
  EXPECT_TRUE(suv.suv());
  EXPECT_FLOAT_EQ(suv.transfer_function().points(0).value(), 2.5f);
  EXPECT_FLOAT_EQ(suv.transfer_function().points(1).value(), 10);
  v1::Fusion off = suv;
  SetGlow(off, false, pet);
  EXPECT_FALSE(Glows(off)) << "without points it shows in slices alone";
  SetGlow(off, true, pet);
  EXPECT_EQ(off.transfer_function().SerializeAsString(), suv.transfer_function().SerializeAsString());
}

}  // namespace
}  // namespace cinevol::viewer
