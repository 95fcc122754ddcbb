// The camera and key-light motion the viewer and the page share (client
// library, view_math.h): a turntable orbit keeps the distance, zoom and pan
// move as a user expects, the key light turns like the eye. The numbers both
// twins must meet are in tests/golden/view_math.json; named views are the
// server's (scene/scene_builder.h), not worked out here.
#include "view_math.h"

#include <gtest/gtest.h>

namespace cinevol {
namespace {

void ExpectNear(Vec3d a, Vec3d b, double tolerance = 1e-6) {
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(a[i], b[i], tolerance) << "component " << i;
}

ViewCamera Front() { return {{0, -500, 0}, {0, 0, 0}, {0, 0, 1}, 30}; }

TEST(CameraControl, OrbitTurnsAboutTheTargetAtTheSameDistance) {
  ViewCamera c = Front();
  Orbit(c, 90, 0);  // dragging right: the eye goes round to the viewer's left (-x)
  ExpectNear(c.eye, {-500, 0, 0});
  ExpectNear(c.up, {0, 0, 1});
  Orbit(c, 0, 90);  // dragging down: the eye rises over the top
  EXPECT_NEAR(Length(c.eye - c.target), 500, 1e-9);
  EXPECT_NEAR(c.eye.z, 500, 1e-9);
  EXPECT_NEAR(Dot(c.up, Normalized(c.target - c.eye)), 0, 1e-12);  // up stays square to the view
}

TEST(CameraControl, ZoomAndPan) {
  ViewCamera c = Front();
  Zoom(c, 0.5);
  ExpectNear(c.eye, {0, -250, 0});
  Zoom(c, 1e-9);  // never onto the target
  EXPECT_GE(Length(c.eye - c.target), 1.0);
  Zoom(c, -2);  // no factor at all: nothing moves
  EXPECT_GE(Length(c.eye - c.target), 1.0);
  c = Front();
  Pan(c, 100, 0, 400);  // the scene follows the cursor to the right: the camera moves left
  EXPECT_LT(c.target.x, 0);
  EXPECT_NEAR(c.eye.x, c.target.x, 1e-9);
  EXPECT_NEAR(DragZoomFactor(100), std::exp(1.0), 1e-12);
  EXPECT_NEAR(WheelZoomFactor(2), 0.81, 1e-12);
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
  EXPECT_NEAR(d.azimuth_deg, 0, 1e-3);
  EXPECT_NEAR(d.elevation_deg, 0, 1e-3);
  SetDirection(light, Front(), {90, 0});  // to the viewer's right (+x), same distance
  EXPECT_NEAR(light.center().x(), 300, 1e-2f);
  EXPECT_NEAR(light.center().y(), 0, 1e-2f);
  SetDirection(light, Front(), {0, 45});
  d = DirectionOf(light, Front());
  EXPECT_NEAR(d.azimuth_deg, 0, 1e-2);
  EXPECT_NEAR(d.elevation_deg, 45, 1e-2);
  // Its face still points at the target: edge_u x edge_v along -center.
  const Vec3d n = Normalized(Cross(ToVec3d(light.edge_u()), ToVec3d(light.edge_v())));
  const Vec3d to_target = -Normalized(ToVec3d(light.center()));
  EXPECT_NEAR(std::abs(Dot(n, to_target)), 1.0, 1e-3);
}

TEST(CameraControl, ProtoRoundTripAndFallback) {
  const ViewCamera c = CameraOf(ToProto(Front()), {});
  ExpectNear(c.eye, Front().eye);
  v1::Camera named;
  named.set_view(v1::LEFT);  // no eye: a view the server has not turned yet
  ExpectNear(CameraOf(named, Front()).eye, Front().eye);
}

}  // namespace
}  // namespace cinevol
