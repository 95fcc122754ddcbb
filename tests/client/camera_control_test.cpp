// The viewer's camera and key-light motion: a turntable orbit keeps the
// distance, zoom and pan move as a user expects, named views follow the
// volume's direction cosines.
#include "viewer/camera_control.h"

#include <gtest/gtest.h>

namespace cinevol::viewer {
namespace {

void ExpectNear(Vec3f a, Vec3f b, float tolerance = 1e-3f) {
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(a[i], b[i], tolerance) << "component " << i;
}

ViewCamera Front() { return {{0, -500, 0}, {0, 0, 0}, {0, 0, 1}, 30}; }

TEST(CameraControl, OrbitTurnsAboutTheTargetAtTheSameDistance) {
  ViewCamera c = Front();
  Orbit(c, 90, 0);  // dragging right: the eye goes round to the viewer's left (-x)
  ExpectNear(c.eye, {-500, 0, 0});
  ExpectNear(c.up, {0, 0, 1});
  Orbit(c, 0, 90);  // dragging down: the eye rises over the top
  EXPECT_NEAR(Length(c.eye - c.target), 500, 1e-2f);
  EXPECT_NEAR(c.eye.z, 500, 1e-2f);
  EXPECT_NEAR(Dot(c.up, Normalize(c.target - c.eye)), 0, 1e-4f);  // up stays square to the view
}

TEST(CameraControl, ZoomAndPan) {
  ViewCamera c = Front();
  Zoom(c, 0.5f);
  ExpectNear(c.eye, {0, -250, 0});
  Zoom(c, 1e-9f);  // never onto the target
  EXPECT_GE(Length(c.eye - c.target), 1.0f);
  c = Front();
  Pan(c, 100, 0, 400);  // the scene follows the cursor to the right: the camera moves left
  EXPECT_LT(c.target.x, 0);
  EXPECT_NEAR(c.eye.x, c.target.x, 1e-4f);
}

TEST(CameraControl, NamedViewsFollowTheDirectionCosines) {
  google::protobuf::RepeatedField<double> identity;
  for (double d : {1, 0, 0, 0, 1, 0, 0, 0, 1}) identity.Add(d);
  const ViewCamera posterior = NamedView(Front(), v1::POSTERIOR, identity);
  ExpectNear(posterior.eye, {0, 500, 0});
  // RAS index axes (x to the patient's right, y anterior): posterior is -y.
  google::protobuf::RepeatedField<double> ras;
  for (double d : {-1, 0, 0, 0, -1, 0, 0, 0, 1}) ras.Add(d);
  ExpectNear(NamedView(Front(), v1::POSTERIOR, ras).eye, {0, -500, 0});
  ExpectNear(NamedView(Front(), v1::SUPERIOR, identity).eye, {0, 0, 500});
}

TEST(CameraControl, TheKeyLightTurnsLikeTheEye) {
  v1::AreaLight light;
  light.mutable_center()->set_y(-300);
  light.mutable_edge_u()->set_x(50);
  light.mutable_edge_v()->set_z(50);
  OrbitLight(light, Front(), 90, 0);
  EXPECT_NEAR(light.center().x(), -300, 1e-2f);
  EXPECT_NEAR(light.center().y(), 0, 1e-2f);
  EXPECT_NEAR(light.edge_u().y(), -50, 1e-2f);  // edges turn with it
}

TEST(CameraControl, TheKeyLightsDirectionIsSetAsSeenFromTheCamera) {
  v1::AreaLight light;
  light.mutable_center()->set_y(-300);  // in front, towards the eye
  light.mutable_edge_u()->set_x(50);
  light.mutable_edge_v()->set_z(50);
  LightDirection d = DirectionOf(light, Front());
  EXPECT_NEAR(d.azimuth_deg, 0, 1e-3f);
  EXPECT_NEAR(d.elevation_deg, 0, 1e-3f);
  SetDirection(light, Front(), {90, 0});  // to the viewer's right (+x), same distance
  EXPECT_NEAR(light.center().x(), 300, 1e-2f);
  EXPECT_NEAR(light.center().y(), 0, 1e-2f);
  SetDirection(light, Front(), {0, 45});
  d = DirectionOf(light, Front());
  EXPECT_NEAR(d.azimuth_deg, 0, 1e-2f);
  EXPECT_NEAR(d.elevation_deg, 45, 1e-2f);
  // Its face still points at the target: edge_u x edge_v along -center.
  const Vec3f n = Normalize(Cross(Vec3f{light.edge_u().x(), light.edge_u().y(), light.edge_u().z()},
                                  Vec3f{light.edge_v().x(), light.edge_v().y(), light.edge_v().z()}));
  const Vec3f to_target = -Normalize(Vec3f{light.center().x(), light.center().y(), light.center().z()});
  EXPECT_NEAR(std::abs(Dot(n, to_target)), 1.0f, 1e-3f);
}

TEST(CameraControl, ProtoRoundTripAndFallback) {
  const ViewCamera c = FromProto(ToProto(Front()), {});
  ExpectNear(c.eye, Front().eye);
  v1::Camera named;
  named.set_view(v1::LEFT);  // no eye: the fallback
  ExpectNear(FromProto(named, Front()).eye, Front().eye);
}

}  // namespace
}  // namespace cinevol::viewer
