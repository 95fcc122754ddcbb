// A scene's two frames (Scene.frame): patient coordinates (LPS, mm: where
// clipping lies, and camera and lights with frame PATIENT_LPS) and the
// volume-centred frame renderers work in (index axes in mm, the volume's box
// centred at the origin: camera and lights of older scene files). Sessions
// and renderers hold scenes in the volume-centred frame; files may be in either.
#pragma once

#include <array>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "core/vec.h"
#include "core/volume.h"

namespace cinevol {

// Where a volume lies in the patient: enough to move between the frames.
struct VolumePlacement {
  std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};  // as VolumeMetadata::direction
  Vec3f origin;  // LPS mm of voxel (0, 0, 0)'s centre
  Vec3f shift;   // half a voxel less half the extent: voxel 0's centre in the volume-centred frame

  static VolumePlacement Of(const Volume& volume);

  Vec3f DirectionToVolume(Vec3f lps) const;  // D^T lps
  Vec3f DirectionToPatient(Vec3f v) const;   // D v
  Vec3f PointToVolume(Vec3f lps) const { return DirectionToVolume(lps - origin) + shift; }
  Vec3f PointToPatient(Vec3f v) const { return DirectionToPatient(v - shift) + origin; }
};

// SessionState.placement for `volume`.
v1::VolumePlacement PlacementMessage(const Volume& volume);

// Moves the camera and lights of a PATIENT_LPS scene into the volume-centred
// frame (frame unset after); a scene already there stays as it is.
void ToVolumeFrame(v1::Scene& scene, const VolumePlacement& placement);
// The other way: a volume-centred scene's camera and lights into patient
// coordinates (frame PATIENT_LPS after); a PATIENT_LPS scene stays as it is.
void ToPatientFrame(v1::Scene& scene, const VolumePlacement& placement);

}  // namespace cinevol
