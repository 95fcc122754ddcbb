// Measurements as DICOM SR through cinevol-server and the `cinevol measurements` command (issue 57), against a
// real Orthanc on loopback: a session's measurements stored into its CT's study and loaded into another session
// within 0.01 mm; who may store (the owner, a principal presenting, nobody else); what cannot be stored or read is
// refused by name.
#include <fmt/format.h>
#include <gdcmAttribute.h>
#include <gdcmReader.h>
#include <gtest/gtest.h>

#include <fstream>
#include <memory>

#include "pacs/dicomweb_client.h"
#include "pacs/handmade_sr.h"
#include "pacs/orthanc_process.h"
#include "pacs/stamped_series.h"
#include "service/server_process.h"
#include "service/service_test_support.h"
#include "support/error_of.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

const SeriesStamp kCt{"2.25.3410571", "2.25.3410571.1", "CINEVOL-SR-SRV", "Cinevol^Measured"};

v1::Vec3 Point(float x, float y, float z) {
  v1::Vec3 p;
  p.set_x(x);
  p.set_y(y);
  p.set_z(z);
  return p;
}

v1::SessionEvent MeasurementsEvent() {
  v1::SessionEvent event;
  auto* list = event.mutable_measurements()->mutable_measurements();
  v1::Measurement* distance = list->Add();
  distance->set_name("lesion");
  *distance->add_points() = Point(-101.234f, 45.678f, -612.5f);
  *distance->add_points() = Point(-80.5f, 60.125f, -600.25f);
  v1::Measurement* angle = list->Add();
  angle->set_name("angle");
  *angle->add_points() = Point(-90, 40, -610);
  *angle->add_points() = Point(-85.5f, 50.25f, -605.75f);
  *angle->add_points() = Point(-70, 41, -611);
  return event;
}

void ExpectSameMeasurements(const google::protobuf::RepeatedPtrField<v1::Measurement>& read,
                            const google::protobuf::RepeatedPtrField<v1::Measurement>& written) {
  ASSERT_EQ(read.size(), written.size());
  for (int i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].name(), written[i].name());
    ASSERT_EQ(read[i].points_size(), written[i].points_size());
    for (int k = 0; k < read[i].points_size(); ++k) {
      EXPECT_NEAR(read[i].points(k).x(), written[i].points(k).x(), 0.01) << i << " " << k;
      EXPECT_NEAR(read[i].points(k).y(), written[i].points(k).y(), 0.01) << i << " " << k;
      EXPECT_NEAR(read[i].points(k).z(), written[i].points(k).z(), 0.01) << i << " " << k;
    }
  }
}

// The value after `label` in `text`, up to the next comma or end of line.
std::string After(const std::string& text, const std::string& label) {
  const std::size_t at = text.find(label);
  if (at == std::string::npos) return {};
  const std::size_t start = at + label.size();
  return text.substr(start, text.find_first_of(",\n", start) - start);
}

class MeasurementsServer : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    skip_ = OrthancProcess::WhatIsMissing();
    if (skip_.empty() && !fs::is_directory(SharedData())) skip_ = "the shared data are not at " + SharedData().string();
    if (!skip_.empty()) return;
    folder_ = fs::temp_directory_path() / fmt::format("cinevol-MeasurementsServer-{}", getpid());
    fs::remove_all(folder_);
    fs::create_directories(folder_);
    orthanc_ = std::make_unique<OrthancProcess>(folder_);
    if (!orthanc_->running()) {
      failure_ = "Orthanc did not start; its log:\n" + orthanc_->Log();
      return;
    }
    const auto files = DicomFilesIn(SharedData() / "ct-body-totalsegmentator/example_ct_dicom");
    const StampedSeries ct = StampSeries({files.begin(), files.begin() + 4}, kCt, folder_ / "ct");
    for (const auto& instance : ct.instances) {
      if (orthanc_->Upload(instance.bytes) != 200) failure_ = "Orthanc refused an upload";
    }
    const pacs::PacsConfig config = orthanc_->Pacs();
    std::ofstream(folder_ / "pacs-credentials")
        << "orthanc basic " << config.credentials.user << ":" << config.credentials.password << "\n";
    std::ofstream(folder_ / "tokens") << "alice-token alice\nbob-token bob\ncarol-token carol\n";
  }

  static void TearDownTestSuite() {
    orthanc_.reset();
    if (!folder_.empty()) fs::remove_all(folder_);
  }

  void SetUp() override {
    if (!skip_.empty()) GTEST_SKIP() << skip_ << "; skipping";
    ASSERT_TRUE(failure_.empty()) << failure_;
    server_ = std::make_unique<ServerProcess>(
        scratch_.path(),
        std::vector<std::string>{"--pacs", "orthanc=" + orthanc_->root_url() + "/dicom-web", "--pacs-credentials",
                                 (folder_ / "pacs-credentials").string(), "--auth-tokens",
                                 (folder_ / "tokens").string(), "--pacs-timeout-seconds", "10"});
    ASSERT_TRUE(server_->running()) << server_->Log();
  }

  // `cinevol ARGS --server ADDR --token TOKEN`: its exit code and output.
  std::pair<int, std::string> Cli(std::vector<std::string> args, const std::string& token = "alice-token") {
    args.insert(args.end(), {"--server", server_->address(), "--token", token});
    return RunProgram(CliPath(), args, scratch_ / "cli.log", 120s);
  }

  // A session of alice's on the CT from the PACS (or `orientation` given over its files').
  std::string CtSession(Client& client, const std::string& orientation = {}) {
    v1::LoadSeriesRequest load;
    load.set_pacs("orthanc");
    load.set_study_uid(kCt.study_uid);
    load.set_series_uid(kCt.series_uid);
    load.set_orientation(orientation);
    v1::CreateSessionRequest session = SmallSession();
    session.set_volume_id(client.LoadSeries(load).id());
    return client.CreateSession(session).session_id();
  }

  static inline std::string skip_, failure_;
  static inline fs::path folder_;
  static inline std::unique_ptr<OrthancProcess> orthanc_;
  ScratchDir scratch_;
  std::unique_ptr<ServerProcess> server_;
};

TEST_F(MeasurementsServer, StoredFromOneSessionAndLoadedIntoAnotherWithinAHundredthOfAMillimetre) {
  Client alice = server_->Connect("alice-token");
  const std::string measured = CtSession(alice);
  const v1::SessionEvent event = MeasurementsEvent();
  alice.SendEvents(measured, {event});

  auto [code, out] = Cli({"measurements", "store", "--session", measured, "--to", "orthanc"});
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find(fmt::format("stored in PACS 'orthanc': study {}", kCt.study_uid)), std::string::npos) << out;
  const std::string series_uid = After(out, ", series ");
  const std::string instance_uid = After(out, ", instance ");
  ASSERT_FALSE(series_uid.empty()) << out;

  const std::vector<v1::SeriesSummary> series = alice.SearchSeries("orthanc", kCt.study_uid);
  const auto sr =
      std::find_if(series.begin(), series.end(), [&](const auto& s) { return s.series_uid() == series_uid; });
  ASSERT_NE(sr, series.end()) << out;
  EXPECT_EQ(sr->modality(), "SR");
  EXPECT_EQ(sr->description(), "cinevol measurements");

  // Printed, then sent to another session as its measurements.
  std::tie(code, out) =
      Cli({"measurements", "load", "--pacs", "orthanc", "--study", kCt.study_uid, "--series", series_uid});
  ASSERT_EQ(code, 0) << out;
  for (const char* expected : {"lesion", "distance", "angle", "mm", "deg", "frame of reference 1.3.12.2.1107.5.1.4"}) {
    EXPECT_NE(out.find(expected), std::string::npos) << expected << "\n" << out;
  }
  EXPECT_NE(out.find("measured series " + kCt.series_uid), std::string::npos) << out;
  const std::string shown = CtSession(alice);
  std::tie(code, out) = Cli({"measurements", "load", "--pacs", "orthanc", "--study", kCt.study_uid, "--series",
                             series_uid, "--instance", instance_uid, "--session", shown});
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find("sent 2 measurements to session " + shown), std::string::npos) << out;
  EXPECT_EQ(out.find("note:"), std::string::npos) << "the same series: " << out;
  ExpectSameMeasurements(alice.SendEvents(shown, {}).scene().measurements(), event.measurements().measurements());

  // The library's call answers the same.
  v1::LoadMeasurementsRequest request;
  request.set_pacs("orthanc");
  request.set_study_uid(kCt.study_uid);
  request.set_series_uid(series_uid);
  const v1::LoadMeasurementsResponse loaded = alice.LoadMeasurements(request);
  ExpectSameMeasurements(loaded.measurements(), event.measurements().measurements());
  EXPECT_EQ(loaded.source_series_uid(), kCt.series_uid);
  EXPECT_EQ(loaded.frame_of_reference_uid(), "1.3.12.2.1107.5.1.4.60064.30000022120807274275100000041");
}

// A report as OHIF writes a length measured on a slice (2D coordinates on the image, in a Comprehensive SR): placed
// in patient coordinates with that slice's plane, which the server asks the PACS for.
TEST_F(MeasurementsServer, ALengthOnASliceAsOhifWritesItIsPlacedWithTheSlicesPlane) {
  gdcm::Reader slice;
  slice.SetFileName((folder_ / "ct" / "2.dcm").c_str());
  ASSERT_TRUE(slice.Read());
  gdcm::Attribute<0x0020, 0x0032> position;
  gdcm::Attribute<0x0020, 0x0037> orientation;
  gdcm::Attribute<0x0028, 0x0030> spacing;
  position.SetFromDataSet(slice.GetFile().GetDataSet());
  orientation.SetFromDataSet(slice.GetFile().GetDataSet());
  spacing.SetFromDataSet(slice.GetFile().GetDataSet());
  HandmadeReport about;
  about.study_uid = kCt.study_uid;
  about.series_uid = "2.25.3410571.99";
  about.instance_uid = "2.25.3410571.99.1";
  about.sop_class = "1.2.840.10008.5.1.4.1.1.88.33";
  about.patient_id = kCt.patient_id;
  about.evidence_series = kCt.series_uid;
  about.evidence_instances = {{"1.2.840.10008.5.1.4.1.1.2", kCt.series_uid + ".2"}};
  const std::vector<float> pixels{100.5f, 200.5f, 140.25f, 260.75f};
  const std::string report = Report({Group({Tracking("Cornerstone3DTools@^0.1.0:Length"), FreeTextFinding("node"),
                                            Num(kLength, "mm", "10", Scoord(pixels, kCt.series_uid + ".2"))})},
                                    {}, about);
  pacs::DicomWebClient(orthanc_->Pacs()).StoreInstances(kCt.study_uid, {report});

  Client alice = server_->Connect("alice-token");
  v1::LoadMeasurementsRequest request;
  request.set_pacs("orthanc");
  request.set_study_uid(kCt.study_uid);
  request.set_series_uid(about.series_uid);
  const v1::LoadMeasurementsResponse loaded = alice.LoadMeasurements(request);
  ASSERT_EQ(loaded.measurements_size(), 1);
  EXPECT_EQ(loaded.measurements(0).name(), "node");
  EXPECT_EQ(loaded.frame_of_reference_uid(), "1.3.12.2.1107.5.1.4.60064.30000022120807274275100000041");
  ASSERT_EQ(loaded.measurements(0).points_size(), 2);
  for (int k = 0; k < 2; ++k) {
    // The centre of pixel (0, 0) is (0.5, 0.5): columns along the row, rows down the column.
    const double column = pixels[2 * k] - 0.5, row = pixels[2 * k + 1] - 0.5;
    double expected[3];
    for (int axis = 0; axis < 3; ++axis) {
      expected[axis] = position.GetValue(axis) + orientation.GetValue(axis) * column * spacing.GetValue(1) +
                       orientation.GetValue(3 + axis) * row * spacing.GetValue(0);
    }
    const v1::Vec3& p = loaded.measurements(0).points(k);
    EXPECT_NEAR(p.x(), expected[0], 0.01);
    EXPECT_NEAR(p.y(), expected[1], 0.01);
    EXPECT_NEAR(p.z(), expected[2], 0.01);
  }
}

TEST_F(MeasurementsServer, TheOwnerAndAPrincipalPresentingMayStoreNobodyElse) {
  Client alice = server_->Connect("alice-token");
  Client bob = server_->Connect("bob-token");
  Client carol = server_->Connect("carol-token");
  const std::string session = CtSession(alice);
  alice.SendEvents(session, {MeasurementsEvent()});
  const auto refused = [&](Client& client) {
    try {
      client.StoreMeasurements(session, "orthanc");
    } catch (const RpcError& e) {
      return e.code();
    }
    return grpc::StatusCode::OK;
  };
  EXPECT_EQ(refused(bob), grpc::StatusCode::PERMISSION_DENIED);
  v1::ShareSessionRequest share;
  share.set_session_id(session);
  share.set_principal("carol");
  share.set_role(v1::VIEWER);
  alice.Share(share);
  EXPECT_EQ(refused(carol), grpc::StatusCode::PERMISSION_DENIED) << "a viewer does not store";
  share.set_principal("bob");
  share.set_role(v1::PRESENTER);
  alice.Share(share);
  const v1::StoredObject stored = bob.StoreMeasurements(session, "orthanc");
  EXPECT_EQ(stored.study_uid(), kCt.study_uid);
  EXPECT_EQ(stored.pacs(), "orthanc");
  EXPECT_FALSE(alice.StoreMeasurements(session, "orthanc").sop_instance_uid().empty()) << "the owner still may";
}

TEST_F(MeasurementsServer, WhatCannotBeStoredOrReadIsRefusedByName) {
  Client alice = server_->Connect("alice-token");
  const auto error = [](auto&& call) {
    try {
      call();
    } catch (const RpcError& e) {
      return std::make_pair(e.code(), std::string(e.what()));
    }
    return std::make_pair(grpc::StatusCode::OK, std::string("(no error)"));
  };
  // Nothing to store; a volume from elsewhere; an orientation given over the files'; an unknown PACS.
  const std::string empty = CtSession(alice);
  auto [code, message] = error([&] { alice.StoreMeasurements(empty, "orthanc"); });
  EXPECT_EQ(code, grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(message.find("has no measurements to store"), std::string::npos) << message;
  const std::string phantom = alice.CreateSession(SmallSession()).session_id();
  alice.SendEvents(phantom, {MeasurementsEvent()});
  std::tie(code, message) = error([&] { alice.StoreMeasurements(phantom, "orthanc"); });
  EXPECT_EQ(code, grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(message.find("did not come from a PACS"), std::string::npos) << message;
  const std::string turned = CtSession(alice, "LPI");
  alice.SendEvents(turned, {MeasurementsEvent()});
  std::tie(code, message) = error([&] { alice.StoreMeasurements(turned, "orthanc"); });
  EXPECT_EQ(code, grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(message.find("orientation overridden (@LPI)"), std::string::npos) << message;
  std::tie(code, message) = error([&] { alice.StoreMeasurements(phantom, "http://evil.example/dicom-web"); });
  EXPECT_EQ(code, grpc::StatusCode::INVALID_ARGUMENT);

  // A series of images is no report: several instances, or one that is no SR.
  auto [exit_code, out] =
      Cli({"measurements", "load", "--pacs", "orthanc", "--study", kCt.study_uid, "--series", kCt.series_uid});
  EXPECT_EQ(exit_code, 3) << out;  // a refused call
  EXPECT_NE(out.find("holds 4 instances; name the report"), std::string::npos) << out;
  std::tie(exit_code, out) = Cli({"measurements", "load", "--pacs", "orthanc", "--study", kCt.study_uid, "--series",
                                  kCt.series_uid, "--instance", kCt.series_uid + ".1"});
  EXPECT_EQ(exit_code, 3) << out;  // a refused call
  // The CT is JPEG 2000: refused by its transfer syntax before a byte of its data set is read.
  EXPECT_NE(out.find("transfer syntax 1.2.840.10008.1.2.4.90, which cinevol does not read"),
            std::string::npos)
      << out;
  std::tie(exit_code, out) = Cli({"measurements", "load", "--pacs", "orthanc", "--study", "1.2.x", "--series", "1.2"});
  EXPECT_EQ(exit_code, 3) << out;  // a refused call
  EXPECT_NE(out.find("study_uid is not a DICOM UID"), std::string::npos) << out;
}

}  // namespace
}  // namespace cinevol::testing
