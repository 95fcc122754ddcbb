// The reading tools' geometry: see reading_view.h.
#include "viewer/reading_view.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace cinevol::viewer {
namespace {

constexpr float kPi = 3.14159265358979f;

std::string Signed(float v, const char* plus, const char* minus) {
  return fmt::format("{} {:.1f}", v >= 0 ? plus : minus, std::fabs(v));
}

}  // namespace

Vec3f ToVec3f(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

v1::Vec3 ToProtoVec3(Vec3f v) {
  v1::Vec3 out;
  out.set_x(v.x);
  out.set_y(v.y);
  out.set_z(v.z);
  return out;
}

std::string PatientPosition(Vec3f lps) {
  return fmt::format("{} {} {} mm", Signed(lps.x, "L", "R"), Signed(lps.y, "P", "A"), Signed(lps.z, "S", "I"));
}

std::string DescribePick(const v1::PickResult& pick, const std::string& value_unit) {
  if (!pick.hit()) return "no hit: the ray left the volume before it became opaque enough";
  std::string text = fmt::format("{}, value {:.1f}{}{}", PatientPosition(ToVec3f(pick.position_mm())), pick.value(),
                                 value_unit.empty() ? "" : " ", value_unit);
  if (pick.has_label()) text += fmt::format(", label {} {}", pick.label().value(), pick.label().name());
  return text;
}

SliceGeometry SliceGeometry::Of(const v1::SliceImage& image) {
  return {ToVec3f(image.origin_mm()), ToVec3f(image.row_direction()), ToVec3f(image.column_direction()),
          image.row_spacing_mm(), image.column_spacing_mm(), int(image.width()), int(image.height())};
}

Vec3f SlicePixelToPatient(const SliceGeometry& slice, float column, float row) {
  return slice.origin + slice.row * (column * slice.row_spacing) + slice.column * (row * slice.column_spacing);
}

SlicePixel PatientToSlicePixel(const SliceGeometry& slice, Vec3f lps) {
  const Vec3f d = lps - slice.origin;
  return {Dot(d, slice.row) / slice.row_spacing, Dot(d, slice.column) / slice.column_spacing,
          Dot(d, Normalize(Cross(slice.row, slice.column)))};
}

float DistanceMm(Vec3f a, Vec3f b) { return Length(a - b); }

float AngleDeg(Vec3f a, Vec3f vertex, Vec3f b) {
  const float cosine = Dot(Normalize(a - vertex), Normalize(b - vertex));
  return std::acos(std::clamp(cosine, -1.0f, 1.0f)) * 180.0f / kPi;
}

std::string MeasurementText(const v1::Measurement& m) {
  if (m.points_size() == kDistancePoints) {
    return fmt::format("{:.1f} mm", DistanceMm(ToVec3f(m.points(0)), ToVec3f(m.points(1))));
  }
  if (m.points_size() == kAnglePoints) {
    return fmt::format("{:.1f} deg", AngleDeg(ToVec3f(m.points(0)), ToVec3f(m.points(1)), ToVec3f(m.points(2))));
  }
  return "";
}

std::optional<ViewPoint> ProjectToView(const ViewCamera& camera, Vec3f world, float width, float height) {
  const Vec3f forward = Normalize(camera.target - camera.eye);
  const Vec3f right = Normalize(Cross(forward, camera.up)), up = Cross(right, forward);
  const Vec3f d = world - camera.eye;
  const float depth = Dot(d, forward);
  if (depth <= 1e-6f) return std::nullopt;
  // Pixels per unit of tan(angle): the vertical field of view spans the height.
  const float scale = 0.5f * height / std::tan(0.5f * camera.fov_y_deg * kPi / 180.0f);
  return ViewPoint{0.5f * width + Dot(d, right) / depth * scale, 0.5f * height - Dot(d, up) / depth * scale};
}

std::vector<MarkerAxis> MarkerAxes(const ViewCamera& camera, const VolumePlacement& placement) {
  const Vec3f forward = Normalize(camera.target - camera.eye);
  const Vec3f right = Normalize(Cross(forward, camera.up)), up = Cross(right, forward);
  static constexpr struct {
    Vec3f lps;
    char plus, minus;
  } kAxes[] = {{{1, 0, 0}, 'L', 'R'}, {{0, 1, 0}, 'P', 'A'}, {{0, 0, 1}, 'S', 'I'}};
  std::vector<MarkerAxis> axes;
  for (const auto& axis : kAxes) {
    const Vec3f w = placement.DirectionToVolume(axis.lps);  // the camera lives in the volume-centred frame
    const MarkerAxis plus{axis.plus, Dot(w, right), Dot(w, up), -Dot(w, forward)};
    axes.push_back(plus);
    axes.push_back({axis.minus, -plus.x, -plus.y, -plus.depth});
  }
  std::sort(axes.begin(), axes.end(), [](const MarkerAxis& a, const MarkerAxis& b) { return a.depth < b.depth; });
  return axes;
}

int CrossedAxis(v1::SliceAxis axis) { return axis == v1::SAGITTAL ? 0 : axis == v1::CORONAL ? 1 : 2; }

v1::SliceRequest CrosshairSlice(const std::string& session_id, v1::SliceAxis axis, Vec3f crosshair) {
  v1::SliceRequest request;
  request.set_session_id(session_id);
  request.set_axis(axis);
  request.set_position_mm(crosshair[CrossedAxis(axis)]);
  return request;
}

float VoxelStepMm(const v1::VolumeInfo& volume, int lps_axis) {
  const float spacing[3] = {volume.spacing_mm().x(), volume.spacing_mm().y(), volume.spacing_mm().z()};
  if (volume.direction_size() != 9) return spacing[lps_axis] > 0 ? spacing[lps_axis] : 1.0f;
  int best = 0;  // direction[3*r + c]: the patient component r of index axis c
  for (int c = 1; c < 3; ++c) {
    if (std::fabs(volume.direction(3 * lps_axis + c)) > std::fabs(volume.direction(3 * lps_axis + best))) best = c;
  }
  return spacing[best] > 0 ? spacing[best] : 1.0f;
}

}  // namespace cinevol::viewer
