// A session's measurements as a DICOM SR measurement report (issue 57): written as a Comprehensive 3D SR with
// DCMTK's dcmsr (TID 1500, a TID 1501 group per distance or angle, its points as SCOORD3D in the frame of reference
// of the series measured), and read back from any report of that shape (cinevol's, OHIF's) by cinevol's own
// bounded parser (part10_reader.h), never by a library that may assert on hostile bytes.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "pacs/secondary_capture.h"

namespace cinevol::pacs {

// Comprehensive 3D SR Storage (PS3.4 B.5): SCOORD3D needs it (or Extensible SR).
inline constexpr const char* kComprehensive3dSrSopClass = "1.2.840.10008.5.1.4.1.1.88.34";
// A report's series number: past the acquired series and renders (kRenderSeriesNumber).
inline constexpr int kMeasurementSeriesNumber = 9901;
// The most measurements a report holds, written or read: a session's (scene/scene_file.h).
inline constexpr std::size_t kMaxReportMeasurements = 64;
// The largest report LoadMeasurements fetches and reads.
inline constexpr std::size_t kMaxReportBytes = std::size_t{16} << 20;

// A distance (2 points) or an angle at the middle one of 3, in patient coordinates (LPS, mm) of the frame of
// reference the report names.
struct ReportMeasurement {
  std::string name;  // at most 64 characters, UTF-8; may be empty
  std::vector<std::array<double, 3>> points;
  // Read from 2D coordinates on an image (SCOORD): `points` are (column, row, 0) in that image's pixels until
  // PlaceOnImage puts them in patient coordinates. Empty for 3D coordinates.
  std::string image_uid = {};        // the image's SOP Instance UID
  std::string image_study_uid = {};  // its study and series, as the report's evidence lists them (empty where it does not)
  std::string image_series_uid = {};
};

// Where an image lies in patient coordinates (its Image Plane module).
struct ImagePlane {
  std::array<double, 3> position{};  // (0020,0032) the centre of its first pixel, LPS mm
  std::array<double, 6>
      orientation{};                   // (0020,0037) the direction along a row (columns increasing), then down a column
  std::array<double, 2> spacing{};     // (0028,0030) mm between rows, then between columns
  std::string frame_of_reference_uid;  // (0020,0052)
};

// `m`'s pixel points on `plane` as patient coordinates (SCOORD's pixels: (0, 0) is the top left corner of the top
// left pixel, whose centre is (0.5, 0.5)), its image fields cleared. InputError for a plane that is none
// (orientation not two unit vectors at right angles, spacing not positive) or points that land beyond +-1e6 mm.
void PlaceOnImage(ReportMeasurement& m, const ImagePlane& plane);

// One image of the series measured, for the report's image library and evidence.
struct ReportImage {
  std::string sop_class_uid;
  std::string sop_instance_uid;
};

// What the measurements were made on: the source series, its frame of reference and its images.
struct ReportSource {
  std::string frame_of_reference_uid;  // required: the coordinates' frame
  std::vector<ReportImage> images;     // may be empty (then no image library group and no evidence)
};

struct MeasurementReportUids {
  std::string study_uid;  // copied from the source
  std::string series_uid;
  std::string sop_instance_uid;
};

// A DICOM Part 10 Comprehensive 3D SR, explicit VR little endian: patient and study copied from `study` (as a
// Secondary Capture copies them; study.series_uid is the series measured), a new series (number 9901, "cinevol
// measurements") and instance, content TID 1500 "Imaging Measurement Report" with an image library of the
// source's images and a measurement group per measurement: a NUM, Length (410668003, SCT) in mm or Angle (110859,
// DCM) in deg, inferred from a SCOORD3D POLYLINE of its points in `source`'s frame of reference; the name is the
// group's Tracking Identifier. `version` goes into Software Versions. Throws InputError naming the field for a bad
// input (no measurement, more than 64, 2 or 3 points, coordinates finite within +-1e6 mm, UIDs, patient and study
// attributes as their VRs allow). Its UIDs go to `uids_out` where given.
std::string MakeMeasurementReport(const SourceStudy& study, const ReportSource& source,
                                  const std::vector<ReportMeasurement>& measurements, const std::string& version,
                                  MeasurementReportUids* uids_out = nullptr);

// What ReadMeasurementReport finds.
struct ReadReport {
  std::vector<ReportMeasurement> measurements;
  std::string frame_of_reference_uid;  // the one every 3D coordinate is in (empty where there are none)
  std::string source_series_uid;       // the series its evidence references, where it says (the first)
  MeasurementReportUids uids;
  // Measurements it holds that are neither a distance nor an angle (areas,
  // ROIs, a Cobb angle of 4 free points, coordinates on a frame of a multi-frame image).
  std::size_t skipped = 0;
};

// Reads a TID 1500 measurement report (Enhanced, Comprehensive, Comprehensive 3D or Extensible SR, as cinevol,
// OHIF and others write it): each NUM of a measurement group inferred from a SCOORD3D POLYLINE of 2 points (a
// distance) or 3 (an angle; 4 where the middle two coincide, as OHIF writes an angle); or from a SCOORD of as many
// on one single-frame image, left in its pixels for the caller to place (ReportMeasurement::image_uid,
// PlaceOnImage). The name is the group's
// free-text finding where it has one (OHIF's label), else its Tracking Identifier, cut to 64 characters.
// Throws InputError saying what is wrong: not Part 10 or beyond the parser's bounds (part10_reader.h), not an SR
// or not TID 1500, a wrong value type, coordinates that are not finite or beyond +-1e6 mm, coordinates in several
// frames of reference, more than 64 measurements, or none read where it holds some.
ReadReport ReadMeasurementReport(std::string part10_bytes);

}  // namespace cinevol::pacs
