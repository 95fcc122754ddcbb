#include "scene/scene_frame.h"

#include "cinevol/v1/scene_vectors.h"

namespace cinevol {
namespace {

Vec3f ToVec(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

void Set(v1::Vec3* to, Vec3f v) {
  to->set_x(v.x);
  to->set_y(v.y);
  to->set_z(v.z);
}

}  // namespace

VolumePlacement VolumePlacement::Of(const Volume& volume) {
  const VolumeMetadata& m = volume.metadata();
  return {m.direction, Vec3f{float(m.origin_mm[0]), float(m.origin_mm[1]), float(m.origin_mm[2])},
          volume.spacing_mm() * 0.5f - volume.extent_mm() * 0.5f};
}

v1::VolumePlacement PlacementMessage(const Volume& volume) {
  const VolumeMetadata& m = volume.metadata();
  v1::VolumePlacement p;
  for (double d : m.direction) p.add_direction(d);
  Set(p.mutable_origin_mm(), Vec3f{float(m.origin_mm[0]), float(m.origin_mm[1]), float(m.origin_mm[2])});
  Set(p.mutable_spacing_mm(), volume.spacing_mm());
  p.mutable_dims()->set_x(std::uint32_t(volume.dims().x));
  p.mutable_dims()->set_y(std::uint32_t(volume.dims().y));
  p.mutable_dims()->set_z(std::uint32_t(volume.dims().z));
  return p;
}

Vec3f VolumePlacement::DirectionToVolume(Vec3f lps) const {
  Vec3f v;
  for (int c = 0; c < 3; ++c) {
    v[c] = float(direction[0 * 3 + c] * lps.x + direction[1 * 3 + c] * lps.y + direction[2 * 3 + c] * lps.z);
  }
  return v;
}

Vec3f VolumePlacement::DirectionToPatient(Vec3f v) const {
  Vec3f lps;
  for (int r = 0; r < 3; ++r) {
    lps[r] = float(direction[r * 3 + 0] * v.x + direction[r * 3 + 1] * v.y + direction[r * 3 + 2] * v.z);
  }
  return lps;
}

void ToVolumeFrame(v1::Scene& scene, const VolumePlacement& p) {
  if (scene.frame() != v1::PATIENT_LPS) return;
  ForEachCameraAndLightVector(
      scene, [&](v1::Vec3* v) { Set(v, p.PointToVolume(ToVec(*v))); },
      [&](v1::Vec3* v) { Set(v, p.DirectionToVolume(ToVec(*v))); });
  scene.clear_frame();
}

void ToPatientFrame(v1::Scene& scene, const VolumePlacement& p) {
  if (scene.frame() == v1::PATIENT_LPS) return;
  ForEachCameraAndLightVector(
      scene, [&](v1::Vec3* v) { Set(v, p.PointToPatient(ToVec(*v))); },
      [&](v1::Vec3* v) { Set(v, p.DirectionToPatient(ToVec(*v))); });
  scene.set_frame(v1::PATIENT_LPS);
}

}  // namespace cinevol
