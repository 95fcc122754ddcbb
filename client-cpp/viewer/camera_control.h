// Camera and key-light manipulation as in 3D Slicer and OsiriX: a turntable
// orbit about the target, zoom along the view, pan in the view plane, the six
// named views, and the key light turned about the target like the eye.
// World space is the server's: mm, the volume centred at the origin.
#pragma once

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "core/vec.h"

namespace cinevol::viewer {

struct ViewCamera {
  Vec3f eye{0, -1000, 0}, target{0, 0, 0}, up{0, 0, 1};
  float fov_y_deg = 30;
};

// A camera with eye/target/up (a session's camera carries them, named
// views resolved); `fallback` when it has none.
ViewCamera FromProto(const v1::Camera& camera, const ViewCamera& fallback);
v1::Camera ToProto(const ViewCamera& camera);

// Degrees the eye turns per pixel dragged.
inline constexpr float kDegreesPerPixel = 0.4f;

// Turns the eye about the target: `yaw_deg` about the screen's up, `pitch_deg`
// about its right axis (up turns with it, so the poles can be crossed).
void Orbit(ViewCamera& camera, float yaw_deg, float pitch_deg);
// Moves the eye towards the target: factor < 1 closer. Never onto the target.
void Zoom(ViewCamera& camera, float factor);
// Moves eye and target in the view plane so that the point under the cursor
// follows it: `dx`, `dy` in pixels of a viewport `viewport_height` tall.
void Pan(ViewCamera& camera, float dx, float dy, int viewport_height);
// The named view about the current target at the current distance.
// `direction` is VolumeInfo.direction (the volume's direction cosines).
ViewCamera NamedView(const ViewCamera& camera, v1::NamedView view,
                     const google::protobuf::RepeatedField<double>& direction);
// Turns an area light about the camera's target as Orbit turns the eye.
void OrbitLight(v1::AreaLight& light, const ViewCamera& camera, float yaw_deg, float pitch_deg);

// Where an area light sits as seen from the camera: azimuth (degrees, 0 in
// front of the volume towards the eye, positive to the viewer's right) and
// elevation (degrees above the view's horizontal plane through the target).
struct LightDirection {
  float azimuth_deg = 0, elevation_deg = 0;
};
LightDirection DirectionOf(const v1::AreaLight& light, const ViewCamera& camera);
// Moves the light to that direction at the same distance from the target,
// turning it so that it faces the target as before.
void SetDirection(v1::AreaLight& light, const ViewCamera& camera, LightDirection direction);

}  // namespace cinevol::viewer
