// Measurement reports: written with DCMTK's DSRDocument, read with cinevol's own Part 10 parser.
#include "pacs/measurement_report.h"

#include <dcmtk/config/osconfig.h>  // first, as DCMTK asks
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmsr/dsrdoc.h>
#include <dcmtk/dcmsr/dsrnumvl.h>
#include <dcmtk/dcmsr/dsrsc3vl.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <numbers>
#include <optional>
#include <set>

#include "core/error.h"
#include "pacs/dcmtk_writing.h"
#include "pacs/dicom_json.h"
#include "pacs/part10_reader.h"

namespace cinevol::pacs {
namespace {

constexpr double kMaxCoordinate = 1e6;     // mm, as a session's measurements
constexpr std::size_t kMaxNameBytes = 64;  // a session's (scene_file.h): bytes

// ---- Codes (PS3.16) ----

struct Code {
  const char* value;
  const char* scheme;
  const char* meaning;
  DSRCodedEntryValue Entry() const { return DSRCodedEntryValue(value, scheme, meaning); }
};

constexpr Code kImagingMeasurementReport{"126000", "DCM", "Imaging Measurement Report"};
constexpr Code kLanguage{"121049", "DCM", "Language of Content Item and Descendants"};
constexpr Code kEnglish{"en-US", "RFC5646", "English (United States)"};
constexpr Code kObserverType{"121005", "DCM", "Observer Type"};
constexpr Code kDevice{"121007", "DCM", "Device"};
constexpr Code kDeviceObserverUid{"121012", "DCM", "Device Observer UID"};
constexpr Code kDeviceObserverName{"121013", "DCM", "Device Observer Name"};
constexpr Code kProcedureReported{"121058", "DCM", "Procedure reported"};
constexpr Code kImagingProcedure{"363679005", "SCT", "Imaging procedure"};
constexpr Code kImageLibrary{"111028", "DCM", "Image Library"};
constexpr Code kImageLibraryGroup{"126200", "DCM", "Image Library Group"};
constexpr Code kFrameOfReferenceUid{"112227", "DCM", "Frame of Reference UID"};
constexpr Code kImagingMeasurements{"126010", "DCM", "Imaging Measurements"};
constexpr Code kMeasurementGroup{"125007", "DCM", "Measurement Group"};
constexpr Code kTrackingIdentifier{"112039", "DCM", "Tracking Identifier"};
constexpr Code kTrackingUid{"112040", "DCM", "Tracking Unique Identifier"};
constexpr Code kLength{"410668003", "SCT", "Length"};
constexpr Code kAngle{"110859", "DCM", "Angle"};
constexpr Code kMillimetre{"mm", "UCUM", "mm"};
constexpr Code kDegree{"deg", "UCUM", "deg"};

// ---- Writing ----

void Require(const OFCondition& condition, const std::string& what) {
  pacs::Require(condition, "the measurement report", what);
}

std::string Decimal(double value) {
  std::string text = fmt::format("{:.4f}", value);  // DS: at most 16 characters
  if (text.size() > 16) text = fmt::format("{:.9g}", value);
  return text;
}

// Names become a TEXT value: control characters (which a label may hold) read as spaces.
std::string TextValue(std::string name) {
  for (char& c : name) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = ' ';
  }
  return WithoutTrailingSpaces(std::move(name));
}

using Point = std::array<double, 3>;

double Distance(const Point& a, const Point& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

// The angle at `vertex` between the arms to `a` and `b`, in degrees; nullopt when an arm has no length.
std::optional<double> AngleDegrees(const Point& a, const Point& vertex, const Point& b) {
  const Point u{a[0] - vertex[0], a[1] - vertex[1], a[2] - vertex[2]};
  const Point v{b[0] - vertex[0], b[1] - vertex[1], b[2] - vertex[2]};
  const double nu = std::hypot(u[0], u[1], u[2]), nv = std::hypot(v[0], v[1], v[2]);
  if (nu <= 0 || nv <= 0) return std::nullopt;
  const double cosine = (u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / (nu * nv);
  return std::acos(std::clamp(cosine, -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

void CheckMeasurements(const std::vector<ReportMeasurement>& measurements) {
  if (measurements.empty()) Refuse("measurements", "is empty: there is nothing to store");
  if (measurements.size() > kMaxReportMeasurements) {
    Refuse("measurements", fmt::format("holds {}; at most {}", measurements.size(), kMaxReportMeasurements));
  }
  for (std::size_t i = 0; i < measurements.size(); ++i) {
    const ReportMeasurement& m = measurements[i];
    const std::string field = fmt::format("measurements[{}]", i);
    if (m.points.size() != 2 && m.points.size() != 3) {
      Refuse(field + ".points", fmt::format("holds {}; a distance has 2, an angle 3", m.points.size()));
    }
    for (const Point& p : m.points) {
      for (double c : p) {
        if (!std::isfinite(c) || std::abs(c) > kMaxCoordinate) {
          Refuse(field + ".points", "holds a coordinate that is not finite or beyond +-1e6 mm");
        }
      }
    }
    if (m.points.size() == 3 && !AngleDegrees(m.points[0], m.points[1], m.points[2])) {
      Refuse(field + ".points", "is an angle one of whose arms has no length");
    }
    if (CleanText(m.name, m.name.size() + 1) != m.name) Refuse(field + ".name", "is not valid UTF-8");
  }
}

// Content items added below a parent, by node id.
class Tree {
 public:
  explicit Tree(DSRDocumentTree& tree) : tree_(tree) {}

  std::size_t Add(std::size_t parent, DSRTypes::E_RelationshipType relation, DSRTypes::E_ValueType type,
                  const Code& concept_name) {
    if (tree_.gotoNode(parent) == 0) throw std::runtime_error("the measurement report: a lost content item");
    const std::size_t id = tree_.addContentItem(relation, type, DSRTypes::AM_belowCurrent);
    if (id == 0) {
      throw std::runtime_error(fmt::format("the measurement report: DCMTK refuses a {} {} below its parent",
                                           DSRTypes::relationshipTypeToReadableName(relation),
                                           DSRTypes::valueTypeToReadableName(type)));
    }
    Require(Item().setConceptName(concept_name.Entry()), concept_name.meaning);
    return id;
  }
  DSRContentItem& Item() { return tree_.getCurrentContentItem(); }

 private:
  DSRDocumentTree& tree_;
};

void AddMeasurementGroup(Tree& tree, std::size_t measurements_node, const ReportMeasurement& m,
                         const std::string& frame_of_reference) {
  const std::size_t group =
      tree.Add(measurements_node, DSRTypes::RT_contains, DSRTypes::VT_Container, kMeasurementGroup);
  Require(tree.Item().setContinuityOfContent(DSRTypes::COC_Separate), "group continuity");
  const std::string name = TextValue(m.name);
  if (!name.empty()) {  // an empty name stays empty when read back
    tree.Add(group, DSRTypes::RT_hasObsContext, DSRTypes::VT_Text, kTrackingIdentifier);
    Require(tree.Item().setStringValue(name.c_str()), "Tracking Identifier");
  }
  tree.Add(group, DSRTypes::RT_hasObsContext, DSRTypes::VT_UIDRef, kTrackingUid);
  Require(tree.Item().setStringValue(NewUid().c_str()), "Tracking Unique Identifier");
  const bool angle = m.points.size() == 3;
  const double value =
      angle ? *AngleDegrees(m.points[0], m.points[1], m.points[2]) : Distance(m.points[0], m.points[1]);
  const std::size_t num = tree.Add(group, DSRTypes::RT_contains, DSRTypes::VT_Num, angle ? kAngle : kLength);
  Require(tree.Item().setNumericValue(
              DSRNumericMeasurementValue(Decimal(value).c_str(), (angle ? kDegree : kMillimetre).Entry())),
          "measured value");
  tree.Add(num, DSRTypes::RT_inferredFrom, DSRTypes::VT_SCoord3D, {"121112", "DCM", "Source of Measurement"});
  DSRSpatialCoordinates3DValue coordinates(DSRTypes::GT3_Polyline);
  for (const Point& p : m.points) coordinates.getGraphicDataList().addItem(float(p[0]), float(p[1]), float(p[2]));
  Require(coordinates.setFrameOfReferenceUID(frame_of_reference.c_str()), "Referenced Frame of Reference UID");
  Require(tree.Item().setSpatialCoordinates3D(coordinates), "coordinates");
}

}  // namespace

std::string MakeMeasurementReport(const SourceStudy& study, const ReportSource& source,
                                  const std::vector<ReportMeasurement>& measurements, const std::string& version,
                                  MeasurementReportUids* uids_out) {
  QuietDcmtk();
  CheckMeasurements(measurements);
  const std::string study_uid = WithoutTrailingSpaces(study.study_uid);
  if (!IsValidUid(study_uid)) Refuse("source.study_uid", "is not a DICOM UID (1 to 64 digits and dots)");
  const std::string series_uid = WithoutTrailingSpaces(study.series_uid);
  if (!IsValidUid(series_uid)) Refuse("source.series_uid", "is not a DICOM UID (1 to 64 digits and dots)");
  if (!IsValidUid(source.frame_of_reference_uid)) {
    Refuse("source.frame_of_reference_uid", "is not a DICOM UID (1 to 64 digits and dots)");
  }
  for (std::size_t i = 0; i < source.images.size(); ++i) {
    if (!IsValidUid(source.images[i].sop_class_uid) || !IsValidUid(source.images[i].sop_instance_uid)) {
      Refuse(fmt::format("source.images[{}]", i), "has a SOP class or instance UID that is not a DICOM UID");
    }
  }
  if (version.empty() || version.size() > 64 || !IsAscii(version)) Refuse("version", "is not 1 to 64 ASCII characters");

  DSRDocument document(DSRTypes::DT_Comprehensive3DSR);
  Require(document.createNewSeriesInStudy(study_uid.c_str()), "the study");
  const bool ascii =
      IsAscii(study.patient_name) && IsAscii(study.patient_id) && IsAscii(study.study_id) &&
      IsAscii(study.accession_number) && IsAscii(study.referring_physician) && IsAscii(study.study_description) &&
      std::all_of(measurements.begin(), measurements.end(), [](const ReportMeasurement& m) { return IsAscii(m.name); });
  if (!ascii) Require(document.setSpecificCharacterSetType(DSRTypes::CS_UTF8), "the character set");
  using Setter = OFCondition (DSRDocument::*)(const OFString&, const OFBool);
  const auto set = [&](const char* field, const std::string& value, std::size_t max_characters, Setter setter) {
    SetChecked(std::string("source.") + field, value, max_characters,
               setter == &DSRDocument::setPatientName || setter == &DSRDocument::setReferringPhysicianName,
               [&](const OFString& v, OFBool check) { return (document.*setter)(v, check); });
  };
  set("patient_name", study.patient_name, 64, &DSRDocument::setPatientName);  // PN: 64 a group
  set("patient_id", study.patient_id, 64, &DSRDocument::setPatientID);        // LO
  set("patient_birth_date", study.patient_birth_date, 8, &DSRDocument::setPatientBirthDate);
  set("patient_sex", study.patient_sex, 16, &DSRDocument::setPatientSex);
  set("study_id", study.study_id, 16, &DSRDocument::setStudyID);  // SH
  set("study_date", study.study_date, 8, &DSRDocument::setStudyDate);
  set("study_time", study.study_time, 16, &DSRDocument::setStudyTime);
  set("accession_number", study.accession_number, 16, &DSRDocument::setAccessionNumber);
  set("referring_physician", study.referring_physician, 64, &DSRDocument::setReferringPhysicianName);
  set("study_description", study.study_description, 64, &DSRDocument::setStudyDescription);
  Require(document.setSeriesDescription("cinevol measurements"), "Series Description");
  Require(document.setSeriesNumber(std::to_string(kMeasurementSeriesNumber).c_str()), "Series Number");
  Require(document.setInstanceNumber("1"), "Instance Number");
  Require(document.setManufacturer("cinevol"), "Manufacturer");
  Require(document.setSoftwareVersions(version.c_str()), "Software Versions");
  const DicomNow now = CurrentDateTime();
  Require(document.setContentDate(now.date.c_str()), "Content Date");
  Require(document.setContentTime(now.time.c_str()), "Content Time");
  Require(document.setSeriesDate(now.date.c_str()), "Series Date");
  Require(document.setSeriesTime(now.time.c_str()), "Series Time");
  for (const ReportImage& image : source.images) {
    Require(document.getCurrentRequestedProcedureEvidence().addItem(
                study_uid.c_str(), series_uid.c_str(), image.sop_class_uid.c_str(), image.sop_instance_uid.c_str()),
            "the evidence");
  }

  DSRDocumentTree& content = document.getTree();
  const std::size_t root = content.addContentItem(DSRTypes::RT_isRoot, DSRTypes::VT_Container);
  if (root == 0) throw std::runtime_error("the measurement report: DCMTK refuses its root");
  Require(content.getCurrentContentItem().setConceptName(kImagingMeasurementReport.Entry()), "the title");
  Require(content.getCurrentContentItem().setContinuityOfContent(DSRTypes::COC_Separate), "root continuity");
  Require(content.getCurrentContentItem().setTemplateIdentification("1500", "DCMR"), "the template");
  Tree tree(content);
  tree.Add(root, DSRTypes::RT_hasConceptMod, DSRTypes::VT_Code, kLanguage);
  Require(tree.Item().setCodeValue(kEnglish.Entry()), "the language");
  tree.Add(root, DSRTypes::RT_hasObsContext, DSRTypes::VT_Code, kObserverType);
  Require(tree.Item().setCodeValue(kDevice.Entry()), "the observer type");
  tree.Add(root, DSRTypes::RT_hasObsContext, DSRTypes::VT_UIDRef, kDeviceObserverUid);
  Require(tree.Item().setStringValue(NewUid().c_str()), "the device observer");
  tree.Add(root, DSRTypes::RT_hasObsContext, DSRTypes::VT_Text, kDeviceObserverName);
  Require(tree.Item().setStringValue("cinevol"), "the device observer's name");
  tree.Add(root, DSRTypes::RT_hasConceptMod, DSRTypes::VT_Code, kProcedureReported);
  Require(tree.Item().setCodeValue(kImagingProcedure.Entry()), "the procedure");
  const std::size_t library = tree.Add(root, DSRTypes::RT_contains, DSRTypes::VT_Container, kImageLibrary);
  Require(tree.Item().setContinuityOfContent(DSRTypes::COC_Separate), "library continuity");
  if (!source.images.empty()) {
    const std::size_t group = tree.Add(library, DSRTypes::RT_contains, DSRTypes::VT_Container, kImageLibraryGroup);
    Require(tree.Item().setContinuityOfContent(DSRTypes::COC_Separate), "library group continuity");
    tree.Add(group, DSRTypes::RT_hasAcqContext, DSRTypes::VT_UIDRef, kFrameOfReferenceUid);
    Require(tree.Item().setStringValue(source.frame_of_reference_uid.c_str()), "the frame of reference");
    for (const ReportImage& image : source.images) {
      if (content.gotoNode(group) == 0 ||
          content.addContentItem(DSRTypes::RT_contains, DSRTypes::VT_Image, DSRTypes::AM_belowCurrent) == 0) {
        throw std::runtime_error("the measurement report: DCMTK refuses an image library entry");
      }
      Require(tree.Item().setImageReference(
                  DSRImageReferenceValue(image.sop_class_uid.c_str(), image.sop_instance_uid.c_str())),
              "an image library entry");
    }
  }
  const std::size_t imaging = tree.Add(root, DSRTypes::RT_contains, DSRTypes::VT_Container, kImagingMeasurements);
  Require(tree.Item().setContinuityOfContent(DSRTypes::COC_Separate), "measurements continuity");
  for (const ReportMeasurement& m : measurements) AddMeasurementGroup(tree, imaging, m, source.frame_of_reference_uid);

  DcmFileFormat file;
  DcmDataset& dataset = *file.getDataset();
  Require(document.write(dataset), "writing");
  // UIDs under the 2.25 root, as a Secondary Capture's, rather than DCMTK's own root.
  MeasurementReportUids uids{study_uid, NewUid(), NewUid()};
  Require(dataset.putAndInsertString(DCM_SeriesInstanceUID, uids.series_uid.c_str()), "Series Instance UID");
  Require(dataset.putAndInsertString(DCM_SOPInstanceUID, uids.sop_instance_uid.c_str()), "SOP Instance UID");
  const std::string bytes = ToPart10(file, "the measurement report");
  if (uids_out != nullptr) *uids_out = uids;
  return bytes;
}

void PlaceOnImage(ReportMeasurement& m, const ImagePlane& plane) {
  const Point row{plane.orientation[0], plane.orientation[1], plane.orientation[2]};
  const Point column{plane.orientation[3], plane.orientation[4], plane.orientation[5]};
  const auto dot = [](const Point& a, const Point& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
  constexpr double kTolerance = 1e-3;
  if (std::abs(dot(row, row) - 1) > kTolerance || std::abs(dot(column, column) - 1) > kTolerance ||
      std::abs(dot(row, column)) > kTolerance) {
    throw InputError(
        fmt::format("image {}: its Image Orientation (Patient) is not two unit vectors at right angles", m.image_uid));
  }
  if (!(plane.spacing[0] > 0 && plane.spacing[1] > 0 && plane.spacing[0] < 1e4 && plane.spacing[1] < 1e4)) {
    throw InputError(fmt::format("image {}: its Pixel Spacing is not within (0, 1e4) mm", m.image_uid));
  }
  for (Point& p : m.points) {
    // Column x runs along the row, spaced by the column spacing; row y down the column, by the row spacing.
    const double along_row = (p[0] - 0.5) * plane.spacing[1], down_column = (p[1] - 0.5) * plane.spacing[0];
    for (int axis = 0; axis < 3; ++axis) {
      p[axis] = plane.position[axis] + row[axis] * along_row + column[axis] * down_column;
      if (!std::isfinite(p[axis]) || std::abs(p[axis]) > kMaxCoordinate) {
        throw InputError(fmt::format("image {}: a point lands beyond +-1e6 mm", m.image_uid));
      }
    }
  }
  m.image_uid.clear();
  m.image_study_uid.clear();
  m.image_series_uid.clear();
}

// ---- Reading ----

namespace {

namespace tag {
constexpr std::uint32_t kSpecificCharacterSet = 0x00080005;
constexpr std::uint32_t kSopClassUid = 0x00080016;
constexpr std::uint32_t kSopInstanceUid = 0x00080018;
constexpr std::uint32_t kCodeValue = 0x00080100;
constexpr std::uint32_t kCodingSchemeDesignator = 0x00080102;
constexpr std::uint32_t kCodeMeaning = 0x00080104;
constexpr std::uint32_t kLongCodeValue = 0x00080119;
constexpr std::uint32_t kUrnCodeValue = 0x00080120;
constexpr std::uint32_t kReferencedSeriesSequence = 0x00081115;
constexpr std::uint32_t kReferencedSopInstanceUid = 0x00081155;
constexpr std::uint32_t kReferencedFrameNumber = 0x00081160;
constexpr std::uint32_t kReferencedSopSequence = 0x00081199;
constexpr std::uint32_t kStudyInstanceUid = 0x0020000D;
constexpr std::uint32_t kSeriesInstanceUid = 0x0020000E;
constexpr std::uint32_t kMeasurementUnitsCodeSequence = 0x004008EA;
constexpr std::uint32_t kValueType = 0x0040A040;
constexpr std::uint32_t kConceptNameCodeSequence = 0x0040A043;
constexpr std::uint32_t kTextValue = 0x0040A160;
constexpr std::uint32_t kConceptCodeSequence = 0x0040A168;
constexpr std::uint32_t kMeasuredValueSequence = 0x0040A300;
constexpr std::uint32_t kCurrentEvidence = 0x0040A375;
constexpr std::uint32_t kContentSequence = 0x0040A730;
constexpr std::uint32_t kGraphicData = 0x00700022;
constexpr std::uint32_t kGraphicType = 0x00700023;
constexpr std::uint32_t kReferencedFrameOfReferenceUid = 0x30060024;
}  // namespace tag

// The SR storage classes whose content may be TID 1500.
constexpr const char* kReportClasses[] = {
    "1.2.840.10008.5.1.4.1.1.88.22",  // Enhanced SR
    "1.2.840.10008.5.1.4.1.1.88.33",  // Comprehensive SR
    kComprehensive3dSrSopClass,       // Comprehensive 3D SR
    "1.2.840.10008.5.1.4.1.1.88.35",  // Extensible SR
};

// Where a middle pair of points counts as one (OHIF writes an angle as the polyline p1, p2, p2, p3).
constexpr double kSameMiddlePoint = 1e-3;  // mm

struct CodeRead {
  std::string value, scheme, meaning;
  bool Is(const Code& code) const { return value == code.value && scheme == code.scheme; }
};

class ReportReader {
 public:
  explicit ReportReader(const Part10Dataset& data) : d_(data) {
    charset_ = d_.Text(d_.root(), tag::kSpecificCharacterSet).value_or("");
  }

  ReadReport Read() {
    const Part10Item& root = d_.root();
    ReadReport report;
    const std::string sop_class = d_.Text(root, tag::kSopClassUid).value_or("");
    if (std::find(std::begin(kReportClasses), std::end(kReportClasses), sop_class) == std::end(kReportClasses)) {
      throw InputError(
          fmt::format("not a measurement report: SOP class {} is not a structured report cinevol reads "
                      "(Enhanced, Comprehensive, Comprehensive 3D or Extensible SR)",
                      sop_class.empty() ? "(none)" : Clean(sop_class, 64)));
    }
    report.uids = {d_.Text(root, tag::kStudyInstanceUid).value_or(""),
                   d_.Text(root, tag::kSeriesInstanceUid).value_or(""),
                   d_.Text(root, tag::kSopInstanceUid).value_or("")};
    const CodeRead title = ConceptName(root);
    if (ValueType(root) != "CONTAINER" || !title.Is(kImagingMeasurementReport)) {
      throw InputError(fmt::format(
          "not a measurement report (TID 1500): its root is a {} ({}, {}, \"{}\"), not a "
          "CONTAINER (126000, DCM, \"Imaging Measurement Report\")",
          Clean(ValueType(root), 16), Clean(title.value, 64), Clean(title.scheme, 16), Clean(title.meaning, 64)));
    }
    report.source_series_uid = ReadEvidence(root);
    bool imaging = false;
    for (const Part10Item* child : d_.Items(root, tag::kContentSequence)) {
      if (ValueType(*child) != "CONTAINER" || !ConceptName(*child).Is(kImagingMeasurements)) continue;
      imaging = true;
      for (const Part10Item* group : d_.Items(*child, tag::kContentSequence)) {
        ++groups_;
        if (ValueType(*group) != "CONTAINER" || !ConceptName(*group).Is(kMeasurementGroup)) continue;
        try {
          ReadGroup(*group, report);
        } catch (const InputError& e) {
          throw InputError(fmt::format("measurement group {}: {}", groups_, e.what()));
        }
      }
    }
    if (!imaging) {
      throw InputError(
          "not a measurement report cinevol reads: it holds no Imaging Measurements container (126010, "
          "DCM)");
    }
    if (report.measurements.size() > kMaxReportMeasurements) {
      throw InputError(fmt::format("the report holds {} distances and angles; a session holds at most {}",
                                   report.measurements.size(), kMaxReportMeasurements));
    }
    if (report.measurements.empty() && report.skipped > 0) {
      throw InputError(
          fmt::format("the report holds {} measurement{}, none a distance or an angle that cinevol reads "
                      "(in 3D coordinates, or 2D on a single-frame image)",
                      report.skipped, report.skipped == 1 ? "" : "s"));
    }
    report.frame_of_reference_uid = frame_of_reference_;
    return report;
  }

 private:
  // Text from the file as valid UTF-8 of at most `max_bytes` bytes (cut between characters), control characters
  // as spaces.
  std::string Clean(const std::string& raw, std::size_t max_bytes) const {
    std::string utf8;
    if (charset_ == "ISO_IR 100") {  // Latin-1: each byte its code point
      for (unsigned char c : raw) {
        if (c < 0x80) {
          utf8 += char(c);
        } else {
          utf8 += char(0xC0 | (c >> 6));
          utf8 += char(0x80 | (c & 0x3F));
        }
      }
    } else {
      utf8 = raw;  // UTF-8 (ISO_IR 192) or ASCII; anything else is made valid below
    }
    for (char& c : utf8) {
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = ' ';
    }
    return CleanText(utf8, max_bytes);
  }

  std::string ValueType(const Part10Item& item) const { return d_.Text(item, tag::kValueType).value_or(""); }

  CodeRead CodeOf(const Part10Item& item, std::uint32_t sequence) const {
    const std::vector<const Part10Item*> items = d_.Items(item, sequence);
    if (items.empty()) return {};
    const Part10Item& code = *items.front();
    std::string value = d_.Text(code, tag::kCodeValue).value_or("");
    if (value.empty()) value = d_.Text(code, tag::kLongCodeValue).value_or("");
    if (value.empty()) value = d_.Text(code, tag::kUrnCodeValue).value_or("");
    return {value, d_.Text(code, tag::kCodingSchemeDesignator).value_or(""),
            d_.Text(code, tag::kCodeMeaning).value_or("")};
  }
  CodeRead ConceptName(const Part10Item& item) const { return CodeOf(item, tag::kConceptNameCodeSequence); }

  // The first series the evidence references; and where each instance it lists lies (evidence_).
  std::string ReadEvidence(const Part10Item& root) {
    std::string first;
    for (const Part10Item* study : d_.Items(root, tag::kCurrentEvidence)) {
      const std::string study_uid = d_.Text(*study, tag::kStudyInstanceUid).value_or("");
      for (const Part10Item* series : d_.Items(*study, tag::kReferencedSeriesSequence)) {
        const std::string uid = d_.Text(*series, tag::kSeriesInstanceUid).value_or("");
        if (!IsValidUid(uid)) continue;
        if (first.empty()) first = uid;
        for (const Part10Item* instance : d_.Items(*series, tag::kReferencedSopSequence)) {
          const std::string sop = d_.Text(*instance, tag::kReferencedSopInstanceUid).value_or("");
          if (IsValidUid(sop)) evidence_.emplace(sop, std::pair{IsValidUid(study_uid) ? study_uid : "", uid});
        }
      }
    }
    return first;
  }

  // The group's name: OHIF's free-text label (a Finding or Finding Site coded
  // CORNERSTONEFREETEXT or CS3DTEXT), else its Tracking Identifier.
  std::string GroupName(const Part10Item& group) const {
    std::string tracking;
    for (const Part10Item* item : d_.Items(group, tag::kContentSequence)) {
      const std::string type = ValueType(*item);
      const CodeRead concept_name = ConceptName(*item);
      if (type == "CODE") {
        const CodeRead value = CodeOf(*item, tag::kConceptCodeSequence);
        if (value.value == "CORNERSTONEFREETEXT" || value.value == "CS3DTEXT")
          return Clean(value.meaning, kMaxNameBytes);
      }
      if (type == "TEXT" && concept_name.Is(kTrackingIdentifier) && tracking.empty()) {
        tracking = Clean(d_.Text(*item, tag::kTextValue).value_or(""), kMaxNameBytes);
      }
    }
    return tracking;
  }

  // Graphic Data of `item` (a SCOORD or SCOORD3D of `dimensions` coordinates a point): 2 to 4 points, finite and
  // within +-1e6; nullopt (skipped) for a graphic type or a number of points that is no distance or angle.
  std::optional<std::vector<Point>> GraphicPoints(const Part10Item& item, std::size_t dimensions) const {
    const std::string graphic = d_.Text(item, tag::kGraphicType).value_or("");
    if (graphic != "POLYLINE" && graphic != "MULTIPOINT") return std::nullopt;
    const Part10Element* data = d_.Find(item, tag::kGraphicData);
    if (data == nullptr) throw InputError("coordinates without Graphic Data (0070,0022)");
    if (!data->Is("FL") && !data->Is("FD")) {
      throw InputError(fmt::format("DICOM: (0070,0022) has VR {}; FL (32-bit floats) was expected", data->Vr()));
    }
    const std::size_t values = data->value.size() / (data->Is("FD") ? 8 : 4);
    if (values < 2 * dimensions || values > 4 * dimensions) return std::nullopt;  // a longer polyline is neither
    const std::vector<double> flat = d_.Floats(item, tag::kGraphicData, 4 * dimensions);
    if (flat.size() % dimensions != 0) {
      throw InputError("coordinates whose Graphic Data is not a whole number of points");
    }
    for (double c : flat) {
      if (!std::isfinite(c)) throw InputError("its coordinates hold a value that is not finite (NaN or infinity)");
      if (std::abs(c) > kMaxCoordinate) throw InputError("its coordinates lie beyond +-1e6 mm");
    }
    std::vector<Point> points;
    for (std::size_t i = 0; i < flat.size(); i += dimensions) {
      points.push_back({flat[i], flat[i + 1], dimensions == 3 ? flat[i + 2] : 0.0});
    }
    return points;
  }

  // The one single-frame image a SCOORD was selected from (its IMAGE child); empty where it names none, or a frame
  // of a multi-frame image (whose planes lie per frame).
  std::string SelectedImage(const Part10Item& scoord) const {
    for (const Part10Item* item : d_.Items(scoord, tag::kContentSequence)) {
      if (ValueType(*item) != "IMAGE") continue;
      const std::vector<const Part10Item*> references = d_.Items(*item, tag::kReferencedSopSequence);
      if (references.size() != 1) return {};
      const std::string frame = d_.Text(*references.front(), tag::kReferencedFrameNumber).value_or("");
      if (!frame.empty() && frame != "1") return {};
      const std::string uid = d_.Text(*references.front(), tag::kReferencedSopInstanceUid).value_or("");
      return IsValidUid(uid) ? uid : std::string();
    }
    return {};
  }

  // What a NUM is inferred from: 3D points, or 2D points on an image; nullopt (counted as skipped) when it has
  // neither that cinevol reads.
  std::optional<ReportMeasurement> Coordinates(const Part10Item& num) {
    for (const Part10Item* item : d_.Items(num, tag::kContentSequence)) {
      const std::string type = ValueType(*item);
      if (type == "SCOORD") {
        const std::string image = SelectedImage(*item);
        std::optional<std::vector<Point>> points = GraphicPoints(*item, 2);
        if (image.empty() || !points) return std::nullopt;
        ReportMeasurement m;
        m.points = std::move(*points);
        m.image_uid = image;
        if (const auto it = evidence_.find(image); it != evidence_.end()) {
          std::tie(m.image_study_uid, m.image_series_uid) = it->second;
        }
        return m;
      }
      if (type != "SCOORD3D") continue;
      std::optional<std::vector<Point>> points = GraphicPoints(*item, 3);
      if (!points) return std::nullopt;
      const std::string frame = d_.Text(*item, tag::kReferencedFrameOfReferenceUid).value_or("");
      if (!IsValidUid(frame)) {
        throw InputError("a SCOORD3D without a valid Referenced Frame of Reference UID (3006,0024)");
      }
      if (frame_of_reference_.empty()) frame_of_reference_ = frame;
      if (frame != frame_of_reference_) {
        throw InputError(
            fmt::format("its coordinates are in frame of reference {}, others' in {}; cinevol reads a "
                        "report in one",
                        frame, frame_of_reference_));
      }
      ReportMeasurement m;
      m.points = std::move(*points);
      return m;
    }
    return std::nullopt;
  }

  void ReadGroup(const Part10Item& group, ReadReport& report) {
    const std::string name = GroupName(group);
    struct Found {
      std::string meaning;
      ReportMeasurement measurement;
    };
    std::vector<Found> found;
    for (const Part10Item* item : d_.Items(group, tag::kContentSequence)) {
      if (ValueType(*item) != "NUM") continue;
      std::optional<ReportMeasurement> m = Coordinates(*item);
      if (m && m->points.size() == 4 && Distance(m->points[1], m->points[2]) <= kSameMiddlePoint) {
        m->points = {m->points[0], m->points[1], m->points[3]};
      }
      if (!m || (m->points.size() != 2 && m->points.size() != 3) || !UnitsAgree(*item, m->points.size())) {
        ++report.skipped;
        continue;
      }
      found.push_back({Clean(ConceptName(*item).meaning, kMaxNameBytes), std::move(*m)});
    }
    for (Found& f : found) {
      f.measurement.name = name;
      if (found.size() > 1) {
        f.measurement.name = name.empty() ? f.meaning : Clean(name + ": " + f.meaning, kMaxNameBytes);
      }
      report.measurements.push_back(std::move(f.measurement));
      if (report.measurements.size() > kMaxReportMeasurements) return;  // refused by the caller
    }
  }

  // A NUM's units, where it has them, must fit its points: a length for 2, degrees for 3.
  bool UnitsAgree(const Part10Item& num, std::size_t points) const {
    const std::vector<const Part10Item*> values = d_.Items(num, tag::kMeasuredValueSequence);
    if (values.empty()) return true;
    const std::string units = CodeOf(*values.front(), tag::kMeasurementUnitsCodeSequence).value;
    if (units.empty()) return true;
    static const std::set<std::string> kLengths{"mm", "cm", "m", "um", "nm"};
    return points == 2 ? kLengths.count(units) > 0 : units == "deg";
  }

  const Part10Dataset& d_;
  std::string charset_;
  std::string frame_of_reference_;
  std::map<std::string, std::pair<std::string, std::string>> evidence_;  // instance: study, series
  std::size_t groups_ = 0;
};

}  // namespace

ReadReport ReadMeasurementReport(std::string part10_bytes) {
  Part10Limits limits;
  limits.max_bytes = kMaxReportBytes;
  const Part10Dataset data = Part10Dataset::Read(std::move(part10_bytes), limits);
  return ReportReader(data).Read();
}

}  // namespace cinevol::pacs
