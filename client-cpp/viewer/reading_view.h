// The reading tools' words and requests, without a window (docs/viewer.md,
// "Reading"): a patient position and a pick in words, a measurement's value,
// the identity in a view's corners, and the requests for the slices through
// the crosshair. The geometry under them is the client library's
// (view_math.h, placement.h); web/src/measure.ts and reading.ts are the
// page's twins.
#pragma once

#include <string>
#include <vector>

#include "cinevol/v1/service.pb.h"
#include "view_math.h"

namespace cinevol::viewer {

// A patient position in words: "L 12.0 P 3.5 S 40.0 mm" (LPS signs as letters).
std::string PatientPosition(Vec3d lps);
// A pick's result for people: position, value with its unit, label; "no hit".
std::string DescribePick(const v1::PickResult& pick, const std::string& value_unit);

// Points a measurement of this kind takes: 2 (distance) or 3 (angle).
inline constexpr int kDistancePoints = 2, kAnglePoints = 3;
// Measurements a scene holds at most (Scene.measurements).
inline constexpr int kMaxMeasurements = 64;
// "42.5 mm" (two points) or "37.0 deg" (three); "" otherwise.
std::string MeasurementText(const v1::Measurement& measurement);

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
v1::SliceRequest CrosshairSlice(const std::string& session_id, v1::SliceAxis axis, Vec3d crosshair);

}  // namespace cinevol::viewer
