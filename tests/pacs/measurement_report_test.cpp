// Measurement reports (pacs/measurement_report.h, issue 57): cinevol's own read back within 0.01 mm, checked by
// dciodvfy and read by DCMTK's dsrdump; a report shaped as OHIF writes it read; hostile reports (10^5 items, NaN
// coordinates, wrong value types, deep nesting, every truncation) refused by name; and one stored into a real
// Orthanc, retrieved and read.
#include "pacs/measurement_report.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>

#include "core/error.h"
#include "pacs/dicom_json.h"
#include "pacs/handmade_sr.h"
#include "pacs/measurement_requests.h"
#include "pacs/orthanc_process.h"
#include "pacs/pacs_error.h"
#include "pacs/part10_reader.h"
#include "pacs/stamped_series.h"
#include "support/error_of.h"
#include "support/shell_command.h"
#include "support/test_paths.h"

namespace cinevol::pacs {
namespace {

namespace fs = std::filesystem;
using namespace cinevol::testing;  // ErrorOf, and reports written by hand (handmade_sr.h)

constexpr const char* kFrame = kHandmadeFrame;

SourceStudy Study() {
  SourceStudy study;
  study.patient_name = "Cinevol^Measured";
  study.patient_id = "CINEVOL-SR-1";
  study.patient_birth_date = "19700101";
  study.patient_sex = "O";
  study.study_uid = "2.25.3400351";
  study.study_id = "SR1";
  study.study_date = "20240102";
  study.study_time = "093000";
  study.accession_number = "ACC-SR-1";
  study.referring_physician = "Ref^Erring";
  study.study_description = "Chest CT";
  study.series_uid = "2.25.3400351.1";
  return study;
}

ReportSource Source() {
  ReportSource source;
  source.frame_of_reference_uid = kFrame;
  for (int i = 1; i <= 3; ++i)
    source.images.push_back({"1.2.840.10008.5.1.4.1.1.2", "2.25.3400351.1." + std::to_string(i)});
  return source;
}

// A distance, an angle and an unnamed distance, at coordinates a float holds to about 1e-5 mm.
std::vector<ReportMeasurement> Measurements() {
  return {
      {"aorta", {{-12.3456, 45.6789, -123.4567}, {30.125, -80.5, 210.75}}},
      {"carina angle", {{10.0, 20.0, 30.0}, {-4.25, 7.5, -100.125}, {55.5, -60.0, 12.75}}},
      {"", {{0.5, 0.25, 0.125}, {400.0, -350.5, 999.875}}},
  };
}

void ExpectSamePoints(const std::vector<ReportMeasurement>& read, const std::vector<ReportMeasurement>& written) {
  ASSERT_EQ(read.size(), written.size());
  for (std::size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].name, written[i].name) << i;
    ASSERT_EQ(read[i].points.size(), written[i].points.size()) << i;
    for (std::size_t k = 0; k < read[i].points.size(); ++k) {
      for (int axis = 0; axis < 3; ++axis) {
        EXPECT_NEAR(read[i].points[k][axis], written[i].points[k][axis], 0.01) << i << " point " << k;
      }
    }
  }
}

// ---- cinevol's own reports ----

TEST(MeasurementReport, ReadsBackItsOwnWithinAHundredthOfAMillimetre) {
  MeasurementReportUids uids;
  const std::string report = MakeMeasurementReport(Study(), Source(), Measurements(), "0.9.0", &uids);
  const ReadReport read = ReadMeasurementReport(report);
  ExpectSamePoints(read.measurements, Measurements());
  EXPECT_EQ(read.frame_of_reference_uid, kFrame);
  EXPECT_EQ(read.source_series_uid, Study().series_uid);
  EXPECT_EQ(read.skipped, 0u);
  EXPECT_EQ(read.uids.study_uid, Study().study_uid);
  EXPECT_EQ(read.uids.series_uid, uids.series_uid);
  EXPECT_EQ(read.uids.sop_instance_uid, uids.sop_instance_uid);
  EXPECT_EQ(uids.study_uid, Study().study_uid);
  for (const std::string& uid : {uids.series_uid, uids.sop_instance_uid}) {
    EXPECT_TRUE(IsValidUid(uid)) << uid;
    EXPECT_EQ(uid.rfind("2.25.", 0), 0u) << uid;
  }
  EXPECT_NE(uids.series_uid, Study().series_uid) << "a report is a new series";
}

TEST(MeasurementReport, IsAComprehensive3dSrOfTheStudyItMeasured) {
  const std::string report = MakeMeasurementReport(Study(), Source(), Measurements(), "0.9.0");
  const Part10Dataset data = Part10Dataset::Read(report);
  const auto text = [&](std::uint32_t tag) { return data.Text(data.root(), tag).value_or("(absent)"); };
  EXPECT_EQ(data.transfer_syntax(), "1.2.840.10008.1.2.1");
  EXPECT_EQ(text(0x00080016), kComprehensive3dSrSopClass);
  EXPECT_EQ(text(0x00080060), "SR");
  EXPECT_EQ(text(0x00100010), Study().patient_name);
  EXPECT_EQ(text(0x00100020), Study().patient_id);
  EXPECT_EQ(text(0x0020000D), Study().study_uid);
  EXPECT_EQ(text(0x00080050), Study().accession_number);
  EXPECT_EQ(text(0x00081030), Study().study_description);
  EXPECT_EQ(text(0x00200011), std::to_string(kMeasurementSeriesNumber));
  EXPECT_EQ(text(0x0008103E), "cinevol measurements");
  EXPECT_EQ(text(0x00181020), "0.9.0");
}

TEST(MeasurementReport, NonAsciiNamesAndPatientsAreUtf8) {
  SourceStudy study = Study();
  study.patient_name = "Müller^Zoë";
  std::vector<ReportMeasurement> measurements = Measurements();
  measurements[0].name = "Aorta – Bogen ß";
  const std::string report = MakeMeasurementReport(study, Source(), measurements, "0.9.0");
  const Part10Dataset data = Part10Dataset::Read(report);
  EXPECT_EQ(data.Text(data.root(), 0x00080005).value_or(""), "ISO_IR 192");
  EXPECT_EQ(data.Text(data.root(), 0x00100010).value_or(""), "Müller^Zoë");
  EXPECT_EQ(ReadMeasurementReport(report).measurements[0].name, "Aorta – Bogen ß");
}

// DCMTK's dsrdump (installed by scripts/install-deps.sh with dciodvfy): a check that skipped where it is missing
// could never fail in CI, so its absence fails the test.
TEST(MeasurementReport, DsrdumpReadsTheTemplateAndItsCoordinates) {
  ASSERT_TRUE(Installed("dsrdump")) << "dsrdump (DCMTK) is not installed: run scripts/install-deps.sh";
  cinevol::testing::ScratchDir scratch;
  const fs::path sr = scratch / "report.dcm";
  WriteFile(sr, MakeMeasurementReport(Study(), Source(), Measurements(), "0.9.0"));
  const CommandResult result = RunCommand("dsrdump '" + sr.string() + "'");
  EXPECT_EQ(result.status, 0) << result.output;
  EXPECT_EQ(result.output.rfind("E: ", 0), std::string::npos) << result.output;  // DCMTK's errors and warnings
  EXPECT_EQ(result.output.find("\nE: "), std::string::npos) << result.output;
  EXPECT_EQ(result.output.rfind("W: ", 0), std::string::npos) << result.output;
  EXPECT_EQ(result.output.find("\nW: "), std::string::npos) << result.output;
  for (const char* expected : {"Comprehensive 3D SR Document", "Imaging Measurement Report", "Measurement Group",
                               "Tracking Identifier", "aorta", "Length", "Angle", "SCOORD3D", "POLYLINE"}) {
    EXPECT_NE(result.output.find(expected), std::string::npos) << expected << "\n" << result.output;
  }
}

// Every object cinevol writes passes David Clunie's validator with no error; the report draws no warning either
// (docs/pacs.md would list and justify any).
TEST(MeasurementReport, DciodvfyFindsNoErrorAndNoWarning) {
  ASSERT_TRUE(Installed("dciodvfy")) << "dciodvfy (dicom3tools) is not installed: run scripts/install-deps.sh";
  cinevol::testing::ScratchDir scratch;
  const fs::path sr = scratch / "report.dcm";
  WriteFile(sr, MakeMeasurementReport(Study(), Source(), Measurements(), "0.9.0"));
  const CommandResult result = RunCommand("dciodvfy '" + sr.string() + "'");
  EXPECT_NE(result.output.find("Comprehensive3DSR"), std::string::npos) << "the IOD it checked:\n" << result.output;
  std::istringstream lines(result.output);
  for (std::string line; std::getline(lines, line);) {
    EXPECT_EQ(line.find("Error"), std::string::npos) << result.output;
    if (line.find("Warning") == std::string::npos) continue;
    ADD_FAILURE() << "a warning: " << line << "\n" << result.output;
  }
}

// The same report as DCMTK's dcmconv writes it again in the other syntaxes: implicit VR little endian read (the
// parser knows the VRs of what it reads there), undefined lengths read, deflated and big endian refused by name.
TEST(MeasurementReport, ReadsItsOwnAsDcmconvWritesItInOtherSyntaxes) {
  ASSERT_TRUE(Installed("dcmconv")) << "dcmconv (DCMTK) is not installed: run scripts/install-deps.sh";
  cinevol::testing::ScratchDir scratch;
  const fs::path sr = scratch / "report.dcm";
  WriteFile(sr, MakeMeasurementReport(Study(), Source(), Measurements(), "0.9.0"));
  const auto converted = [&](const std::string& flags) {
    const fs::path out = scratch / "converted.dcm";
    const CommandResult result = RunCommand("dcmconv " + flags + " '" + sr.string() + "' '" + out.string() + "'");
    EXPECT_EQ(result.status, 0) << flags << ": " << result.output;
    return cinevol::testing::ReadWholeFile(out);
  };
  for (const char* flags : {"+ti", "+ti +e", "+te +e"}) {  // +e: sequences and items of undefined length
    const ReadReport read = ReadMeasurementReport(converted(flags));
    ExpectSamePoints(read.measurements, Measurements());
    EXPECT_EQ(read.frame_of_reference_uid, kFrame) << flags;
    EXPECT_EQ(read.source_series_uid, Study().series_uid) << flags;
  }
  EXPECT_NE(ErrorOf<InputError>([&] { ReadMeasurementReport(converted("+td")); }).find("deflated"), std::string::npos);
  EXPECT_NE(ErrorOf<InputError>([&] { ReadMeasurementReport(converted("+tb")); }).find("big endian"),
            std::string::npos);
}

TEST(MeasurementReport, BadInputsAreRefusedNamingTheField) {
  const auto refusal = [](SourceStudy study, ReportSource source, std::vector<ReportMeasurement> measurements) {
    return ErrorOf<InputError>([&] { MakeMeasurementReport(study, source, measurements, "0.9.0"); });
  };
  const auto with = [](auto edit) {
    std::vector<ReportMeasurement> m = Measurements();
    edit(m);
    return m;
  };
  SourceStudy bad_study = Study();
  bad_study.study_uid = "1.2.abc";
  SourceStudy long_id = Study();
  long_id.patient_id = std::string(65, 'X');
  SourceStudy long_name = Study();
  long_name.patient_name = std::string(65, 'N');
  SourceStudy bad_date = Study();
  bad_date.study_date = "2024-01-02";
  SourceStudy control = Study();
  control.patient_name = "Evil\nName";
  ReportSource no_frame = Source();
  no_frame.frame_of_reference_uid = "";
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<std::pair<std::string, std::string>> cases{
      {refusal(bad_study, Source(), Measurements()), "source.study_uid"},
      {refusal(long_id, Source(), Measurements()), "source.patient_id"},
      {refusal(control, Source(), Measurements()), "source.patient_name holds a control character"},
      {refusal(long_name, Source(), Measurements()), "source.patient_name is longer than its VR allows"},
      {refusal(bad_date, Source(), Measurements()), "source.study_date"},
      {refusal(Study(), no_frame, Measurements()), "source.frame_of_reference_uid"},
      {refusal(Study(), Source(), {}), "measurements is empty"},
      {refusal(Study(), Source(), std::vector<ReportMeasurement>(65, Measurements()[0])), "measurements holds 65"},
      {refusal(Study(), Source(), with([](auto& m) {
                 m[1].points.pop_back();
                 m[1].points.pop_back();
               })),
       "measurements[1].points holds 1"},
      {refusal(Study(), Source(), with([&](auto& m) { m[0].points[1][2] = nan; })), "measurements[0].points"},
      {refusal(Study(), Source(), with([](auto& m) { m[2].points[0][0] = 2e6; })), "measurements[2].points"},
      {refusal(Study(), Source(), with([](auto& m) { m[1].points[0] = m[1].points[1]; })),
       "measurements[1].points is an angle one of whose arms has no length"},
      {refusal(Study(), Source(), with([](auto& m) { m[0].name = "\xff\xfe"; })), "measurements[0].name"},
  };
  for (const auto& [message, field] : cases)
    EXPECT_NE(message.find(field), std::string::npos) << field << ": " << message;
}

// ---- Others' reports ----

// As OHIF (dcmjs, Cornerstone3D) writes 3D measurements: the label in a free-text Finding, a length, an angle as a
// Cobb angle's polyline whose middle two points coincide; and a 2D length that names no image, which is skipped.
TEST(MeasurementReport, ReadsAReportAsOhifWritesIt) {
  const Elements length_2d =
      WithChildren(ContentItem("INFERRED FROM", "SCOORD", {"121112", "DCM", "Source of Measurement"}), {});
  const std::string report = Report({
      Group({Tracking("Cornerstone3DTools@^0.1.0:Length"), FreeTextFinding("aorta"),
             Num(kLength, "mm", "42.1", Scoord3d({1.5f, 2.5f, 3.5f, 10.25f, -20.5f, 30.75f}))}),
      Group({Tracking("Cornerstone3DTools@^0.1.0:Angle"),
             Num(kCobbAngle, "deg", "90", Scoord3d({10, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10, 0}))}),
      Group({Tracking("Cornerstone3DTools@^0.1.0:Length"), Num(kLength, "mm", "5", length_2d)}),
  });
  const ReadReport read = ReadMeasurementReport(report);
  ExpectSamePoints(read.measurements, {{"aorta", {{1.5, 2.5, 3.5}, {10.25, -20.5, 30.75}}},
                                       {"Cornerstone3DTools@^0.1.0:Angle", {{10, 0, 0}, {0, 0, 0}, {0, 10, 0}}}});
  EXPECT_EQ(read.skipped, 1u);
  EXPECT_EQ(read.frame_of_reference_uid, kFrame);
  EXPECT_EQ(read.source_series_uid, "2.25.3400359.7");
}

// As OHIF writes a measurement made on a slice: 2D coordinates on an image that the evidence lists, left in its
// pixels for the caller to place with the image's plane.
TEST(MeasurementReport, Reads2dMeasurementsOnAnImageForTheCallerToPlace) {
  HandmadeReport about;
  about.sop_class = "1.2.840.10008.5.1.4.1.1.88.33";  // Comprehensive SR: OHIF's
  about.evidence_instances = {{"1.2.840.10008.5.1.4.1.1.2", "2.25.3400359.7.3"}};
  const std::string report =
      Report({Group({Tracking("Cornerstone3DTools@^0.1.0:Length"), FreeTextFinding("node"),
                     Num(kLength, "mm", "28.3", Scoord({10.5f, 20.5f, 30.5f, 40.5f}, "2.25.3400359.7.3"))})},
             {}, about);
  const ReadReport read = ReadMeasurementReport(report);
  ASSERT_EQ(read.measurements.size(), 1u);
  const ReportMeasurement& m = read.measurements[0];
  EXPECT_EQ(m.name, "node");
  EXPECT_EQ(m.image_uid, "2.25.3400359.7.3");
  EXPECT_EQ(m.image_series_uid, "2.25.3400359.7");
  EXPECT_EQ(m.image_study_uid, "2.25.3400359");
  ASSERT_EQ(m.points.size(), 2u);
  EXPECT_EQ(m.points[1], (std::array<double, 3>{30.5, 40.5, 0}));
  EXPECT_EQ(read.frame_of_reference_uid, "") << "the image's plane names it";
  EXPECT_EQ(read.skipped, 0u);
}

TEST(MeasurementReport, PlaceOnImageFollowsTheImagesPlane) {
  // An axial slice: the first pixel's centre (0.5, 0.5) is its position; columns run along x 0.75 mm apart, rows
  // down y 0.5 mm apart.
  ReportMeasurement m{"d", {{0.5, 0.5, 0}, {10.5, 20.5, 0}}, "2.25.1", "2.25.2", "2.25.3"};
  PlaceOnImage(m, {{-100, -200, 50}, {1, 0, 0, 0, 1, 0}, {0.5, 0.75}, "2.25.9"});
  EXPECT_EQ(m.points[0], (std::array<double, 3>{-100, -200, 50}));
  EXPECT_EQ(m.points[1], (std::array<double, 3>{-92.5, -190, 50}));
  EXPECT_TRUE(m.image_uid.empty() && m.image_series_uid.empty() && m.image_study_uid.empty());
  // A sagittal one: along a row is anterior to posterior (+y), down a column is superior to inferior (-z).
  ReportMeasurement sagittal{"s", {{3.5, 5.5, 0}}, "2.25.1", "", ""};
  PlaceOnImage(sagittal, {{10, -50, 80}, {0, 1, 0, 0, 0, -1}, {2, 1}, "2.25.9"});
  EXPECT_EQ(sagittal.points[0], (std::array<double, 3>{10, -47, 70}));
  ReportMeasurement bad{"b", {{1, 1, 0}}, "2.25.1", "", ""};
  EXPECT_NE(ErrorOf<InputError>([&] {
              PlaceOnImage(bad, {{0, 0, 0}, {1, 0, 0, 1, 0, 0}, {1, 1}, ""});
            }).find("image 2.25.1: its Image Orientation (Patient) is not two unit vectors at right angles"),
            std::string::npos);
  EXPECT_NE(ErrorOf<InputError>([&] {
              PlaceOnImage(bad, {{0, 0, 0}, {1, 0, 0, 0, 1, 0}, {0, 1}, ""});
            }).find("Pixel Spacing"),
            std::string::npos);
}

TEST(MeasurementReport, AReportOfNothingItReadsSaysWhy) {
  // 2D coordinates that name no image, and a polygon of five points.
  const Elements length_2d = ContentItem("INFERRED FROM", "SCOORD", {"121112", "DCM", "Source of Measurement"});
  const std::string message = ErrorOf<InputError>([&] {
    ReadMeasurementReport(Report({Group({Num(kLength, "mm", "5", length_2d)}),
                                  Group({Num(kLength, "mm", "5", Scoord3d(std::vector<float>(15, 1.0f)))})}));
  });
  EXPECT_NE(message.find("holds 2 measurements, none a distance or an angle that cinevol reads"), std::string::npos)
      << message;
}

// ---- Hostile reports ----

TEST(MeasurementReportHostile, AHundredThousandItemsAreRefusedByName) {
  std::string items = TagBytes(0x0040A730) + "SQ" + Le16(0) + Le32(0xffffffff);
  for (int i = 0; i < 100000; ++i) items += TagBytes(0xfffee000) + Le32(0);
  items += TagBytes(0xfffee0dd) + Le32(0);
  const std::string report = Report({}, {{0x0040A730, items}});
  const std::string message = ErrorOf<InputError>([&] { ReadMeasurementReport(report); });
  EXPECT_NE(message.find("more than 32768 sequence items"), std::string::npos) << message;
}

TEST(MeasurementReportHostile, NanAndInfiniteCoordinatesAreRefusedByName) {
  for (const float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    const std::string report = Report({Group({Num(kLength, "mm", "1", Scoord3d({0, 0, 0, 1, bad, 1}))})});
    const std::string message = ErrorOf<InputError>([&] { ReadMeasurementReport(report); });
    EXPECT_NE(message.find("measurement group 1: its coordinates hold a value that is not finite"), std::string::npos)
        << message;
  }
  const std::string far = Report({Group({Num(kLength, "mm", "1", Scoord3d({0, 0, 0, 1, 3e6f, 1}))})});
  EXPECT_NE(ErrorOf<InputError>([&] { ReadMeasurementReport(far); }).find("beyond +-1e6 mm"), std::string::npos);
}

TEST(MeasurementReportHostile, WrongValueTypesAreRefusedByName) {
  Elements text_coordinates = Scoord3d({0, 0, 0, 1, 1, 1});
  text_coordinates[0x00700022] = Element(0x00700022, "DS", "0\\0\\0\\1\\1\\1");
  std::string message =
      ErrorOf<InputError>([&] { ReadMeasurementReport(Report({Group({Num(kLength, "mm", "1", text_coordinates)})})); });
  EXPECT_NE(message.find("(0070,0022) has VR DS; FL (32-bit floats) was expected"), std::string::npos) << message;

  Elements float_type = Num(kLength, "mm", "1", Scoord3d({0, 0, 0, 1, 1, 1}));
  float_type[0x0040A040] = Element(0x0040A040, "FL", Floats({1.0f}));
  message = ErrorOf<InputError>([&] { ReadMeasurementReport(Report({Group({float_type})})); });
  EXPECT_NE(message.find("(0040,A040) has VR FL; a text was expected"), std::string::npos) << message;

  Elements not_a_sequence = Group({});
  not_a_sequence[0x0040A730] = Element(0x0040A730, "LO", "items");
  message = ErrorOf<InputError>([&] { ReadMeasurementReport(Report({not_a_sequence})); });
  EXPECT_NE(message.find("(0040,A730) has VR LO; a sequence (SQ) was expected"), std::string::npos) << message;

  Elements two_frames = Group({Num(kLength, "mm", "1", Scoord3d({0, 0, 0, 1, 1, 1})),
                               Num(kLength, "mm", "1", Scoord3d({0, 0, 0, 2, 2, 2}, "2.25.1"))});
  message = ErrorOf<InputError>([&] { ReadMeasurementReport(Report({two_frames})); });
  EXPECT_NE(message.find("frame of reference 2.25.1, others' in " + std::string(kFrame)), std::string::npos) << message;
}

TEST(MeasurementReportHostile, DeepNestingAndFloodsOfElementsAreRefusedByName) {
  std::string nested = Element(0x00080100, "SH", "deep");
  for (int i = 0; i < 100; ++i) nested = Sequence(0x0040A730, {nested});
  std::string message = ErrorOf<InputError>([&] { ReadMeasurementReport(Report({}, {{0x0040A730, nested}})); });
  EXPECT_NE(message.find("sequences nested more than 24 deep"), std::string::npos) << message;

  std::string flood;
  for (std::uint32_t group : {0x0011u, 0x0013u, 0x0015u, 0x0017u, 0x0019u}) {
    for (std::uint32_t element = 0; element < 0x10000; ++element) flood += Element((group << 16) | element, "LO", "");
  }
  message = ErrorOf<InputError>([&] { ReadMeasurementReport(Report({}, {{0x00110000, flood}})); });
  EXPECT_NE(message.find("more than 262144 data elements"), std::string::npos) << message;

  const std::string huge(kMaxReportBytes + 1, '\0');
  message = ErrorOf<InputError>([&] { ReadMeasurementReport(huge); });
  EXPECT_NE(message.find("cinevol reads at most"), std::string::npos) << message;
}

TEST(MeasurementReportHostile, WhatIsNotAMeasurementReportIsRefused) {
  EXPECT_NE(ErrorOf<InputError>([] { ReadMeasurementReport(std::string(4096, 'x')); }).find("not a DICOM Part 10 file"),
            std::string::npos);
  const std::string deflated = Part10(Element(0x00080016, "UI", kComprehensive3dSrSopClass), "1.2.840.10008.1.2.1.99");
  EXPECT_NE(ErrorOf<InputError>([&] { ReadMeasurementReport(deflated); }).find("deflated"), std::string::npos);
  const std::string other_root =
      Report({}, {{0x0040A043, Sequence(0x0040A043, {CodeItem({"18748-4", "LN", "Report"})})}});
  std::string message = ErrorOf<InputError>([&] { ReadMeasurementReport(other_root); });
  EXPECT_NE(message.find("not a measurement report (TID 1500): its root is a CONTAINER (18748-4, LN, \"Report\")"),
            std::string::npos)
      << message;
  const std::string out_of_order = Part10(Element(0x0020000D, "UI", "2.25.1") + Element(0x00080016, "UI", "2.25.2"));
  message = ErrorOf<InputError>([&] { ReadMeasurementReport(out_of_order); });
  EXPECT_NE(message.find("element (0008,0016) out of order: after (0020,000D)"), std::string::npos) << message;
}

TEST(MeasurementReportHostile, ReadRefusesAnMrSliceOfTheSharedData) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const auto files = cinevol::testing::DicomFilesIn(cinevol::testing::SharedData() / "mr-chest-dicom-seg3d");
  ASSERT_FALSE(files.empty());
  const std::string message =
      ErrorOf<InputError>([&] { ReadMeasurementReport(cinevol::testing::ReadWholeFile(files[0])); });
  EXPECT_NE(message.find("SOP class 1.2.840.10008.5.1.4.1.1.4 is not a structured report"), std::string::npos)
      << message;
}

// A report from a PACS is not trusted: every truncation and every corrupted byte is refused by name or read, and
// never takes the process down or throws anything else.
TEST(MeasurementReportHostile, EveryTruncationAndCorruptedByteIsRefusedOrRead) {
  const std::string report = MakeMeasurementReport(Study(), Source(), Measurements(), "0.9.0");
  std::size_t read_whole = 0;
  const auto read = [&](const std::string& bytes) {
    try {
      if (ReadMeasurementReport(bytes).measurements.size() == Measurements().size()) ++read_whole;
    } catch (const InputError&) {
    }
  };
  for (std::size_t size = 0; size < report.size(); ++size) read(report.substr(0, size));
  EXPECT_EQ(read_whole, 0u) << "a cut report read as whole";
  for (std::size_t at = 0; at < report.size(); ++at) {
    for (const char value : {'\x00', '\xff', '\x80'}) {
      std::string corrupted = report;
      corrupted[at] = value;
      read(corrupted);
    }
  }
}

// ---- Through a real PACS ----

// End to end: the series described (its images and frame of reference, from QIDO-RS), the report stored (STOW-RS)
// into its study on a real Orthanc, retrieved (WADO-RS) and read within 0.01 mm.
TEST(MeasurementReportOrthanc, StoredRetrievedAndReadWithinAHundredthOfAMillimetre) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const std::string missing = cinevol::testing::OrthancProcess::WhatIsMissing();
  if (!missing.empty()) GTEST_SKIP() << missing << "; skipping";
  cinevol::testing::ScratchDir scratch;
  const cinevol::testing::SeriesStamp stamp{"2.25.3400352", "2.25.3400352.1", "CINEVOL-SR-2", "Cinevol^Sr"};
  const auto ct =
      cinevol::testing::DicomFilesIn(cinevol::testing::SharedData() / "ct-body-totalsegmentator" / "example_ct_dicom");
  const auto seeded = cinevol::testing::StampSeries({ct.begin(), ct.begin() + 3}, stamp, scratch / "ct");
  cinevol::testing::OrthancProcess orthanc(scratch.path());
  ASSERT_TRUE(orthanc.running()) << orthanc.Log();
  for (const auto& instance : seeded.instances) ASSERT_EQ(orthanc.Upload(instance.bytes), 200);
  const DicomWebClient client(orthanc.Pacs());

  const ReportSource source = DescribeSourceSeries(client, stamp.study_uid, stamp.series_uid);
  // The files' own frame agrees; another is refused naming both.
  EXPECT_EQ(DescribeSourceSeries(client, stamp.study_uid, stamp.series_uid, source.frame_of_reference_uid)
                .frame_of_reference_uid,
            source.frame_of_reference_uid);
  const std::string other =
      ErrorOf<PacsError>([&] { DescribeSourceSeries(client, stamp.study_uid, stamp.series_uid, "2.25.77"); });
  EXPECT_NE(other.find("whose files named 2.25.77"), std::string::npos) << other;
  EXPECT_EQ(source.frame_of_reference_uid, "1.3.12.2.1107.5.1.4.60064.30000022120807274275100000041");
  ASSERT_EQ(source.images.size(), 3u);
  EXPECT_EQ(source.images[0].sop_class_uid, "1.2.840.10008.5.1.4.1.1.2");

  SourceStudy study = Study();
  study.study_uid = stamp.study_uid;
  study.series_uid = stamp.series_uid;
  study.patient_id = stamp.patient_id;
  study.patient_name = stamp.patient_name;
  MeasurementReportUids uids;
  const std::string report = MakeMeasurementReport(study, source, Measurements(), "0.9.0", &uids);
  EXPECT_EQ(client.StoreInstances(stamp.study_uid, {report}).stored_sop_instance_uids,
            std::vector<std::string>{uids.sop_instance_uid});
  const std::vector<SeriesSummary> series = client.SearchSeries(stamp.study_uid);
  const auto sr =
      std::find_if(series.begin(), series.end(), [&](const auto& s) { return s.series_uid == uids.series_uid; });
  ASSERT_NE(sr, series.end());
  EXPECT_EQ(sr->modality, "SR");

  const std::string retrieved =
      RetrieveInstance(client, stamp.study_uid, uids.series_uid, uids.sop_instance_uid, kMaxReportBytes);
  EXPECT_EQ(retrieved, report) << "Orthanc keeps the report as stored";
  const ReadReport read = ReadMeasurementReport(retrieved);
  ExpectSamePoints(read.measurements, Measurements());
  EXPECT_EQ(read.frame_of_reference_uid, source.frame_of_reference_uid);
  EXPECT_EQ(read.source_series_uid, stamp.series_uid);
  // A retrieve past the limit is refused by name before it is read.
  const std::string message = ErrorOf<InputError>(
      [&] { RetrieveInstance(client, stamp.study_uid, uids.series_uid, uids.sop_instance_uid, 1000); });
  EXPECT_NE(message.find("larger than 1000 bytes, the most cinevol reads of one"), std::string::npos) << message;
}

}  // namespace
}  // namespace cinevol::pacs
