// Where a session's volume lies in the patient (SessionState.placement, or
// the same four fields of a VolumeInfo), and the moves between the two frames
// a session's numbers come in: patient coordinates (LPS, mm: clipping,
// measurements, picks, slices, scene files) and the volume-centred frame the
// camera and lights live in (index axes in mm, the box around the corner
// voxels' centres centred at the origin):
//
//   lps = origin + D * (v + (dims - 1) * spacing / 2)
//
// web/src/placement.ts is the page's twin; tests/golden/view_math.json holds
// the cases both meet.
#pragma once

#include <array>
#include <vector>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "vec3d.h"

namespace cinevol {

class Placement {
 public:
  using Direction = std::array<double, 9>;  // row-major: direction[3*r + c], patient row r of index axis c

  Placement() = default;  // the identity at the origin: one 1 mm voxel
  Placement(const Direction& direction, Vec3d origin_mm, Vec3d spacing_mm, Vec3d dims);
  static Placement Of(const v1::VolumePlacement& placement);
  static Placement Of(const v1::VolumeInfo& volume);  // a volume listed before sessions said where it lies

  // The one fallback for direction cosines: the nine numbers as sent, or the
  // identity where there are not nine finite ones (a volume described by an
  // older server, a placement not yet sent).
  static Direction DirectionOf(const google::protobuf::RepeatedField<double>& direction);

  Vec3d ToPatient(Vec3d volume_point) const;
  Vec3d ToVolume(Vec3d lps) const;
  Vec3d DirectionToPatient(Vec3d v) const;  // D v
  Vec3d DirectionToVolume(Vec3d lps) const;  // D^T lps: D is orthonormal (mirrored or not)
  // A voxel index (fractional: voxel centres at whole numbers) in patient coordinates.
  Vec3d IndexToPatient(Vec3d index) const;

  // One voxel along patient axis `lps_axis` (0 L, 1 P, 2 S), in mm: the
  // spacing of the index axis that runs most nearly along it.
  double VoxelStepMm(int lps_axis) const;
  // Where the plane at `position_mm` along patient axis `lps_axis` cuts the
  // box around the corner voxels' centres (as slices span it): the polygon's
  // corners in order around it (LPS mm); empty where the plane misses it.
  std::vector<Vec3d> SlicePlaneOutline(int lps_axis, double position_mm) const;

  const Direction& direction() const { return direction_; }
  Vec3d origin_mm() const { return origin_; }
  Vec3d spacing_mm() const { return spacing_; }
  Vec3d dims() const { return dims_; }

 private:
  Vec3d HalfExtent() const;  // (dims - 1) * spacing / 2: the centre's index offset in mm

  Direction direction_{1, 0, 0, 0, 1, 0, 0, 0, 1};
  Vec3d origin_, spacing_{1, 1, 1}, dims_{1, 1, 1};
};

// A scene's camera and lights moved into patient coordinates (frame
// PATIENT_LPS after), as a scene file keeps them beside its clipping; a scene
// there already stays as it is.
void MoveSceneToPatient(v1::Scene& scene, const Placement& placement);
// The other way, into the volume-centred frame a session's events use (frame
// unset after); a scene there already stays as it is.
void MoveSceneToVolumeCentred(v1::Scene& scene, const Placement& placement);

}  // namespace cinevol
