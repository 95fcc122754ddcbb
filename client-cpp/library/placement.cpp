// Moves between a volume's patient placement and its volume-centred frame.
#include "placement.h"

#include <algorithm>
#include <cmath>

#include "cinevol/v1/scene_vectors.h"

namespace cinevol {
namespace {

Vec3d Multiply(const Placement::Direction& d, Vec3d v) {
  return {d[0] * v.x + d[1] * v.y + d[2] * v.z, d[3] * v.x + d[4] * v.y + d[5] * v.z,
          d[6] * v.x + d[7] * v.y + d[8] * v.z};
}

Vec3d MultiplyTransposed(const Placement::Direction& d, Vec3d v) {
  return {d[0] * v.x + d[3] * v.y + d[6] * v.z, d[1] * v.x + d[4] * v.y + d[7] * v.z,
          d[2] * v.x + d[5] * v.y + d[8] * v.z};
}

Vec3d DimsOf(const v1::GridSize& dims) { return {double(dims.x()), double(dims.y()), double(dims.z())}; }

}  // namespace

Placement::Placement(const Direction& direction, Vec3d origin_mm, Vec3d spacing_mm, Vec3d dims)
    : direction_(direction), origin_(origin_mm), spacing_(spacing_mm), dims_(dims) {}

Placement::Direction Placement::DirectionOf(const google::protobuf::RepeatedField<double>& direction) {
  const bool usable = direction.size() == 9 &&
                      std::all_of(direction.begin(), direction.end(), [](double d) { return std::isfinite(d); });
  Direction d{1, 0, 0, 0, 1, 0, 0, 0, 1};
  if (usable) std::copy(direction.begin(), direction.end(), d.begin());
  return d;
}

Placement Placement::Of(const v1::VolumePlacement& p) {
  return {DirectionOf(p.direction()), ToVec3d(p.origin_mm()), ToVec3d(p.spacing_mm()), DimsOf(p.dims())};
}

Placement Placement::Of(const v1::VolumeInfo& v) {
  return {DirectionOf(v.direction()), ToVec3d(v.origin_mm()), ToVec3d(v.spacing_mm()), DimsOf(v.dims())};
}

Vec3d Placement::HalfExtent() const {
  return {(dims_.x - 1) * spacing_.x / 2, (dims_.y - 1) * spacing_.y / 2, (dims_.z - 1) * spacing_.z / 2};
}

Vec3d Placement::ToPatient(Vec3d v) const { return origin_ + Multiply(direction_, v + HalfExtent()); }

Vec3d Placement::ToVolume(Vec3d lps) const { return MultiplyTransposed(direction_, lps - origin_) - HalfExtent(); }

Vec3d Placement::DirectionToPatient(Vec3d v) const { return Multiply(direction_, v); }

Vec3d Placement::DirectionToVolume(Vec3d lps) const { return MultiplyTransposed(direction_, lps); }

Vec3d Placement::IndexToPatient(Vec3d index) const {
  return origin_ + Multiply(direction_, {index.x * spacing_.x, index.y * spacing_.y, index.z * spacing_.z});
}

double Placement::VoxelStepMm(int lps_axis) const {
  int best = 0;
  for (int c = 1; c < 3; ++c) {
    if (std::fabs(direction_[3 * lps_axis + c]) > std::fabs(direction_[3 * lps_axis + best])) best = c;
  }
  return spacing_[best] > 0 ? spacing_[best] : 1.0;
}

std::vector<Vec3d> Placement::SlicePlaneOutline(int lps_axis, double position_mm) const {
  const Vec3d last{dims_.x - 1, dims_.y - 1, dims_.z - 1};  // the corner voxels' indices
  const auto corner = [&](int bits) {
    return IndexToPatient({(bits & 1) ? last.x : 0.0, (bits & 2) ? last.y : 0.0, (bits & 4) ? last.z : 0.0});
  };
  std::vector<Vec3d> points;
  for (int a = 0; a < 8; ++a) {
    for (int bit : {1, 2, 4}) {
      if (a & bit) continue;  // each of the 12 edges once, from its lower corner
      const Vec3d p = corner(a), q = corner(a | bit);
      const double da = p[lps_axis] - position_mm, db = q[lps_axis] - position_mm;
      if (da * db > 0 || da == db) continue;
      points.push_back(p + (q - p) * (da / (da - db)));
    }
  }
  if (points.size() < 3) return {};
  // In order around their centre, in the plane's other two axes (in x, y, z order).
  const int u = lps_axis == 0 ? 1 : 0, w = lps_axis == 2 ? 1 : 2;
  Vec3d centre;
  for (const Vec3d& p : points) centre += p / double(points.size());
  std::sort(points.begin(), points.end(), [&](const Vec3d& p, const Vec3d& q) {
    return std::atan2(p[w] - centre[w], p[u] - centre[u]) < std::atan2(q[w] - centre[w], q[u] - centre[u]);
  });
  return points;
}

void MoveSceneToPatient(v1::Scene& scene, const Placement& p) {
  if (scene.frame() == v1::PATIENT_LPS) return;
  ForEachCameraAndLightVector(
      scene, [&](v1::Vec3* v) { *v = ToProto(p.ToPatient(ToVec3d(*v))); },
      [&](v1::Vec3* v) { *v = ToProto(p.DirectionToPatient(ToVec3d(*v))); });
  scene.set_frame(v1::PATIENT_LPS);
}

void MoveSceneToVolumeCentred(v1::Scene& scene, const Placement& p) {
  if (scene.frame() != v1::PATIENT_LPS) return;
  ForEachCameraAndLightVector(
      scene, [&](v1::Vec3* v) { *v = ToProto(p.ToVolume(ToVec3d(*v))); },
      [&](v1::Vec3* v) { *v = ToProto(p.DirectionToVolume(ToVec3d(*v))); });
  scene.clear_frame();
}

}  // namespace cinevol
