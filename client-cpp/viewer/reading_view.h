// The reading tools' geometry, without a window (docs/viewer.md, "Reading"):
// where a slice's pixel lies in the patient and back, where a point falls on
// the 3D view, measurement values, the orientation marker's axes, and the
// requests for the slices through the crosshair. web/src/measure.ts and
// orientation.ts are the browser's twins of these.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "cinevol/v1/service.pb.h"
#include "core/vec.h"
#include "scene/scene_frame.h"
#include "viewer/camera_control.h"

namespace cinevol::viewer {

Vec3f ToVec3f(const v1::Vec3& v);
v1::Vec3 ToProtoVec3(Vec3f v);

// A patient position in words: "L 12.0 P 3.5 S 40.0 mm" (LPS signs as letters).
std::string PatientPosition(Vec3f lps);
// A pick's result for people: position, value with its unit, label; "no hit".
std::string DescribePick(const v1::PickResult& pick, const std::string& value_unit);

// A slice image's pixel grid in the patient (SliceImage's geometry).
struct SliceGeometry {
  Vec3f origin;                               // LPS mm of the top-left pixel's centre
  Vec3f row{1, 0, 0}, column{0, 1, 0};        // unit LPS steps along a row and down a column
  float row_spacing = 1, column_spacing = 1;  // mm per pixel along each
  int width = 0, height = 0;

  static SliceGeometry Of(const v1::SliceImage& image);
};

// Pixel centres at whole numbers: (0, 0) is the top-left pixel's centre.
Vec3f SlicePixelToPatient(const SliceGeometry& slice, float column, float row);

struct SlicePixel {
  float column = 0, row = 0;
  float off_plane_mm = 0;  // signed distance from the slice's plane
};
SlicePixel PatientToSlicePixel(const SliceGeometry& slice, Vec3f lps);

float DistanceMm(Vec3f a, Vec3f b);
// The angle at `vertex` between the rays to `a` and `b`, in degrees.
float AngleDeg(Vec3f a, Vec3f vertex, Vec3f b);
// Points a measurement of this kind takes: 2 (distance) or 3 (angle).
inline constexpr int kDistancePoints = 2, kAnglePoints = 3;
// "42.5 mm" (two points) or "37.0 deg" (three); "" otherwise.
std::string MeasurementText(const v1::Measurement& measurement);

// Where a world point (the camera's frame) falls on a view `width` x `height`
// pixels (y down), as the server's pinhole camera renders it; nullopt behind
// the eye.
struct ViewPoint {
  float x = 0, y = 0;
};
std::optional<ViewPoint> ProjectToView(const ViewCamera& camera, Vec3f world, float width, float height);

// One half-axis of the orientation marker: the letter at its end and its
// direction on screen (x right, y up, in [-1, 1]; depth > 0 towards the eye).
struct MarkerAxis {
  char letter = 'L';
  float x = 0, y = 0, depth = 0;
};
// The six half-axes (L R P A S I) as `camera` (volume-centred frame) sees
// them, farthest first so that nearer ones are drawn over them.
std::vector<MarkerAxis> MarkerAxes(const ViewCamera& camera, const VolumePlacement& placement);

// The top corners of a view for a volume from DICOM: the patient (name, ID)
// at the left, the study (date, description) and the series at the right;
// empty lines left out (the bottom corners hold the marker and the stats).
// Shown on screen only: never printed or logged.
struct IdentityCorners {
  std::vector<std::string> top_left, top_right;
  bool empty() const { return top_left.empty() && top_right.empty(); }
};
IdentityCorners CornersOf(const v1::PatientIdentity& identity);
// A DICOM person name for people: "Doe^John^^Dr" -> "Doe, John Dr" (the
// family name, then given, middle, prefix and suffix; empty parts left out;
// of "alphabetic=ideographic=phonetic" the first).
std::string PersonName(const std::string& dicom_name);
// "20091203" -> "2009-12-03"; anything else as it is.
std::string StudyDate(const std::string& dicom_date);

// The patient axis an axis slice crosses (0: x for sagittal, 1: y for
// coronal, 2: z for axial).
int CrossedAxis(v1::SliceAxis axis);
// The slice of `axis` through `crosshair` (LPS mm).
v1::SliceRequest CrosshairSlice(const std::string& session_id, v1::SliceAxis axis, Vec3f crosshair);
// Where the plane at `position_mm` along patient axis `lps_axis` cuts the
// volume's box (its corner voxels' centres, as the slices span it): the
// polygon's corners in order around it (LPS mm); empty where it misses.
std::vector<Vec3f> SlicePlaneOutline(const v1::VolumeInfo& volume, int lps_axis, float position_mm);
// One voxel along patient axis `lps_axis` (mm): the spacing of the volume's
// index axis that runs most nearly along it.
float VoxelStepMm(const v1::VolumeInfo& volume, int lps_axis);

}  // namespace cinevol::viewer
