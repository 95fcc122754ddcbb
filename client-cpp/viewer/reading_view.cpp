// The reading tools' words and requests: see reading_view.h.
#include "viewer/reading_view.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cinevol::viewer {
namespace {

std::string Signed(double v, const char* plus, const char* minus) {
  return fmt::format("{} {:.1f}", v >= 0 ? plus : minus, std::fabs(v));
}

}  // namespace

std::string PatientPosition(Vec3d lps) {
  return fmt::format("{} {} {} mm", Signed(lps.x, "L", "R"), Signed(lps.y, "P", "A"), Signed(lps.z, "S", "I"));
}

std::string DescribePick(const v1::PickResult& pick, const std::string& value_unit) {
  if (!pick.hit()) return "no hit: the ray left the volume before it became opaque enough";
  std::string text = fmt::format("{}, value {:.1f}{}{}", PatientPosition(ToVec3d(pick.position_mm())), pick.value(),
                                 value_unit.empty() ? "" : " ", value_unit);
  if (pick.has_label()) text += fmt::format(", label {} {}", pick.label().value(), pick.label().name());
  return text;
}

std::string MeasurementText(const v1::Measurement& m) {
  if (m.points_size() == kDistancePoints) {
    return fmt::format("{:.1f} mm", DistanceMm(ToVec3d(m.points(0)), ToVec3d(m.points(1))));
  }
  if (m.points_size() == kAnglePoints) {
    return fmt::format("{:.1f} deg", AngleDeg(ToVec3d(m.points(0)), ToVec3d(m.points(1)), ToVec3d(m.points(2))));
  }
  return "";
}

int CrossedAxis(v1::SliceAxis axis) { return axis == v1::SAGITTAL ? 0 : axis == v1::CORONAL ? 1 : 2; }

v1::SliceRequest CrosshairSlice(const std::string& session_id, v1::SliceAxis axis, Vec3d crosshair) {
  v1::SliceRequest request;
  request.set_session_id(session_id);
  request.set_axis(axis);
  request.set_position_mm(float(crosshair[CrossedAxis(axis)]));
  return request;
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
