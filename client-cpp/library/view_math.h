// What a client works out on its own side to show a session, the server
// having resolved the rest (named views, presets, placement): the camera's
// motion under the mouse (a turntable orbit as in 3D Slicer and OsiriX, zoom
// along the view, pan in the view plane, the key light turned like the eye),
// where a point falls on the view, the orientation marker, a slice image's
// pixels in the patient and measurements. Pure functions in double precision.
// web/src's camera.ts, orientation.ts and measure.ts are the page's twins;
// tests/golden/view_math.json holds the cases both meet.
#pragma once

#include <optional>
#include <vector>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "placement.h"
#include "vec3d.h"

namespace cinevol {

// A camera as numbers, in the volume-centred frame (mm).
struct ViewCamera {
  Vec3d eye{0, -1000, 0}, target{0, 0, 0}, up{0, 0, 1};
  double fov_y_deg = 30;
};

// A state's camera (numbers: the server turned any named view); `fallback`
// where it has no usable eye and target.
ViewCamera CameraOf(const v1::Camera& camera, const ViewCamera& fallback = {});
v1::Camera ToProto(const ViewCamera& camera);

// How the viewer and the page turn the mouse into motion: degrees per pixel
// dragged (orbit, the key light), the zoom factor of a vertical drag of `dy`
// pixels (right button) and of `steps` wheel steps (positive: closer).
inline constexpr double kDegreesPerPixel = 0.4;
double DragZoomFactor(double dy_px);
double WheelZoomFactor(double steps);

// Turns the eye about the target: `yaw_deg` about the screen's up, `pitch_deg`
// about its right axis (up turns with it, so the poles can be crossed).
void Orbit(ViewCamera& camera, double yaw_deg, double pitch_deg);
// Moves the eye towards the target (factor < 1: closer), never nearer than
// 1 mm; a factor that is not a positive number changes nothing.
void Zoom(ViewCamera& camera, double factor);
// Moves eye and target in the view plane so that the point under the cursor
// follows it: `dx`, `dy` in pixels of a view `viewport_height` pixels tall.
void Pan(ViewCamera& camera, double dx, double dy, double viewport_height);

// Turns an area light about the camera's target as Orbit turns the eye.
void OrbitLight(v1::AreaLight& light, const ViewCamera& camera, double yaw_deg, double pitch_deg);
// Where an area light sits as seen from the camera: azimuth (0 towards the
// eye, positive to the viewer's right) and elevation above the view's
// horizontal plane through the target, in degrees.
struct LightDirection {
  double azimuth_deg = 0, elevation_deg = 0;
};
LightDirection DirectionOf(const v1::AreaLight& light, const ViewCamera& camera);
// Moves the light to that direction at the same distance from the target,
// turned so that it faces the target as before.
void SetDirection(v1::AreaLight& light, const ViewCamera& camera, LightDirection direction);

// Where a point of the camera's frame falls on a view `width` x `height`
// pixels (y down), as the server's pinhole camera renders it; nullopt behind
// the eye.
struct ViewPoint {
  double x = 0, y = 0;
};
std::optional<ViewPoint> ProjectToView(const ViewCamera& camera, Vec3d point, double width, double height);

// One half-axis of the orientation marker: the letter at its end and its
// direction on screen (x right, y up, in [-1, 1]; depth > 0 towards the eye).
struct MarkerAxis {
  char letter = 'L';
  double x = 0, y = 0, depth = 0;
};
// The six half-axes (L R P A S I) as `camera` sees them, farthest first so
// that nearer ones are drawn over them.
std::vector<MarkerAxis> MarkerAxes(const ViewCamera& camera, const Placement& placement);

// A slice image's pixel grid in the patient (SliceImage's geometry).
struct SliceGrid {
  Vec3d origin;                                // LPS mm of the top-left pixel's centre
  Vec3d row{1, 0, 0}, column{0, 1, 0};         // unit LPS steps along a row and down a column
  double row_spacing = 1, column_spacing = 1;  // mm per pixel along each
  int width = 0, height = 0;

  static SliceGrid Of(const v1::SliceImage& image);
};
// Pixel centres at whole numbers: (0, 0) is the top-left pixel's centre.
Vec3d SlicePixelToPatient(const SliceGrid& slice, double column, double row);
struct SlicePixel {
  double column = 0, row = 0;
  double off_plane_mm = 0;  // signed distance from the slice's plane, along row x column
};
SlicePixel PatientToSlicePixel(const SliceGrid& slice, Vec3d lps);

double DistanceMm(Vec3d a, Vec3d b);
// The angle at `vertex` between the rays to `a` and `b`, in degrees.
double AngleDeg(Vec3d a, Vec3d vertex, Vec3d b);

}  // namespace cinevol
