// Scene.frame: camera and lights in patient coordinates (PATIENT_LPS, as
// clipping) or in the volume-centred frame of older scene files.
#include "scene/scene_frame.h"

#include <gtest/gtest.h>

#include "io/phantom.h"
#include "scene/session_state.h"

namespace cinevol {
namespace {

// A head stored feet first and upside down (index y runs anterior, z
// inferior: a rotation, so held as it is) with an origin far from 0.
Volume TiltedHead() {
  v1::Phantom head;
  head.set_kind(v1::Phantom::HEAD);
  head.set_size(16);
  const Volume phantom = MakePhantom(head);
  std::vector<float> values(phantom.voxel_count());
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = phantom.ValueAtIndex(i);
  VolumeMetadata m = phantom.metadata();
  m.direction = {1, 0, 0, 0, -1, 0, 0, 0, -1};
  m.origin_mm = {-120.0, 35.5, 900.0};
  return Volume(phantom.dims(), phantom.spacing_mm(), std::move(values), m);
}

v1::Vec3 V(float x, float y, float z) {
  v1::Vec3 v;
  v.set_x(x);
  v.set_y(y);
  v.set_z(z);
  return v;
}

void ExpectNear(const v1::Vec3& a, const v1::Vec3& b, const char* what) {
  EXPECT_NEAR(a.x(), b.x(), 1e-3f) << what;
  EXPECT_NEAR(a.y(), b.y(), 1e-3f) << what;
  EXPECT_NEAR(a.z(), b.z(), 1e-3f) << what;
}

TEST(SceneFrame, ThePatientsPointsAndDirectionsMapToTheVolumeFrameAndBack) {
  const Volume volume = TiltedHead();
  const VolumePlacement p = VolumePlacement::Of(volume);
  // Voxel 0's centre is the origin; the volume's centre is the volume frame's 0.
  const Vec3f origin{-120.0f, 35.5f, 900.0f};
  const Vec3f voxel0 = p.PointToVolume(origin);
  EXPECT_NEAR(voxel0.x, p.shift.x, 1e-3f);
  EXPECT_NEAR(voxel0.z, p.shift.z, 1e-3f);
  // Superior is index -z here.
  EXPECT_NEAR(p.DirectionToVolume({0, 0, 1}).z, -1.0f, 1e-6f);

  v1::Scene scene;
  scene.set_frame(v1::PATIENT_LPS);
  *scene.mutable_camera()->mutable_eye() = V(-100, -400, 950);  // anterior of the head
  *scene.mutable_camera()->mutable_target() = V(-100, 50, 950);
  *scene.mutable_camera()->mutable_up() = V(0, 0, 1);
  v1::AreaLight& lamp = *scene.add_lights()->mutable_area();
  *lamp.mutable_center() = V(0, -300, 1100);
  *lamp.mutable_edge_u() = V(50, 0, 0);
  *lamp.mutable_edge_v() = V(0, 0, 50);
  *scene.add_lights()->mutable_directional()->mutable_direction() = V(0, 1, -1);
  const v1::Scene written = scene;

  ToVolumeFrame(scene, p);
  EXPECT_EQ(scene.frame(), v1::SCENE_FRAME_UNSPECIFIED);
  EXPECT_NEAR(scene.camera().up().z(), -1.0f, 1e-6f) << "the head's top is index -z";
  EXPECT_GT(scene.camera().eye().y(), scene.camera().target().y()) << "anterior is index +y here";
  ToPatientFrame(scene, p);
  EXPECT_EQ(scene.frame(), v1::PATIENT_LPS);
  ExpectNear(scene.camera().eye(), written.camera().eye(), "eye");
  ExpectNear(scene.camera().target(), written.camera().target(), "target");
  ExpectNear(scene.camera().up(), written.camera().up(), "up");
  ExpectNear(scene.lights(0).area().center(), lamp.center(), "lamp centre");
  ExpectNear(scene.lights(0).area().edge_v(), lamp.edge_v(), "lamp edge");
  ExpectNear(scene.lights(1).directional().direction(), written.lights(1).directional().direction(), "sun");
}

TEST(SceneFrame, AnOlderSceneFileStaysInTheVolumeFrame) {
  const VolumePlacement p = VolumePlacement::Of(TiltedHead());
  v1::Scene scene;
  *scene.mutable_camera()->mutable_eye() = V(0, -400, 0);
  ToVolumeFrame(scene, p);
  ExpectNear(scene.camera().eye(), V(0, -400, 0), "unchanged");
}

TEST(SceneFrame, ASessionOfAPatientSceneHoldsItInTheVolumeFrame) {
  const Volume volume = TiltedHead();
  v1::CreateSessionRequest request;
  request.mutable_viewport()->set_width(32);
  request.mutable_viewport()->set_height(32);
  v1::Scene& scene = *request.mutable_scene();
  scene.set_frame(v1::PATIENT_LPS);
  *scene.mutable_camera()->mutable_eye() = V(-100, -400, 950);
  *scene.mutable_camera()->mutable_target() = V(-100, 50, 950);
  const v1::SessionState state = InitialState(request, SceneContext{volume}, {});
  EXPECT_EQ(state.scene().frame(), v1::SCENE_FRAME_UNSPECIFIED);
  const Vec3f eye = VolumePlacement::Of(volume).PointToVolume({-100, -400, 950});
  EXPECT_NEAR(state.scene().camera().eye().z(), eye.z, 1e-3f);
  EXPECT_GT(state.scene().lights_size(), 0) << "no lights: the volume's default ones";
}

}  // namespace
}  // namespace cinevol
