// The reading tools' geometry: see reading_view.h.
#include "viewer/reading_view.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

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
          image.row_spacing_mm(),     image.column_spacing_mm(),      int(image.width()),
          int(image.height())};
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

std::vector<Vec3f> SlicePlaneOutline(const v1::VolumeInfo& volume, int lps_axis, float position_mm) {
  const VolumePlacement placement = VolumePlacement::Of(volume);
  const Vec3f extent{(volume.dims().x() - 1) * volume.spacing_mm().x(),
                     (volume.dims().y() - 1) * volume.spacing_mm().y(),
                     (volume.dims().z() - 1) * volume.spacing_mm().z()};
  const auto corner = [&](int bits) {
    const Vec3f index_mm{(bits & 1) ? extent.x : 0.0f, (bits & 2) ? extent.y : 0.0f, (bits & 4) ? extent.z : 0.0f};
    return placement.origin + placement.DirectionToPatient(index_mm);
  };
  std::vector<Vec3f> points;
  for (int a = 0; a < 8; ++a) {
    for (int bit : {1, 2, 4}) {
      if (a & bit) continue;  // each of the 12 edges once, from its lower corner
      const Vec3f p = corner(a), q = corner(a | bit);
      const float da = p[lps_axis] - position_mm, db = q[lps_axis] - position_mm;
      if (da * db > 0 || da == db) continue;
      points.push_back(p + (q - p) * (da / (da - db)));
    }
  }
  if (points.size() < 3) return {};
  // In order around their centre, in the plane's own two axes.
  const int u = (lps_axis + 1) % 3, w = (lps_axis + 2) % 3;
  Vec3f centre{0, 0, 0};
  for (const Vec3f& p : points) centre = centre + p * (1.0f / float(points.size()));
  std::sort(points.begin(), points.end(), [&](const Vec3f& p, const Vec3f& q) {
    return std::atan2(p[w] - centre[w], p[u] - centre[u]) < std::atan2(q[w] - centre[w], q[u] - centre[u]);
  });
  return points;
}

std::string PersonName(const std::string& dicom_name) {
  const std::string alphabetic = dicom_name.substr(0, dicom_name.find('='));
  std::vector<std::string> parts;
  for (std::size_t start = 0;;) {
    const std::size_t caret = alphabetic.find('^', start);
    std::string part = alphabetic.substr(start, caret == std::string::npos ? std::string::npos : caret - start);
    while (!part.empty() && part.back() == ' ') part.pop_back();
    if (!part.empty()) parts.push_back(std::move(part));
    if (caret == std::string::npos) break;
    start = caret + 1;
  }
  std::string out;
  for (std::size_t i = 0; i < parts.size(); ++i) out += (i == 0 ? "" : i == 1 ? ", " : " ") + parts[i];
  return out;
}

std::string StudyDate(const std::string& dicom_date) {
  const bool digits = dicom_date.size() == 8 && dicom_date.find_first_not_of("0123456789") == std::string::npos;
  return digits ? dicom_date.substr(0, 4) + "-" + dicom_date.substr(4, 2) + "-" + dicom_date.substr(6, 2) : dicom_date;
}

IdentityCorners CornersOf(const v1::PatientIdentity& identity) {
  IdentityCorners corners;
  const auto add = [](std::vector<std::string>& lines, const std::string& line) {
    if (!line.empty()) lines.push_back(line);
  };
  add(corners.top_left, PersonName(identity.patient_name()));
  add(corners.top_left, identity.patient_id().empty() ? "" : "ID " + identity.patient_id());
  add(corners.top_right, StudyDate(identity.study_date()));
  add(corners.top_right, identity.study_description());
  add(corners.top_right, identity.series_description());
  return corners;
}

}  // namespace cinevol::viewer
