// cinevol-server with a real PACS: Debian's Orthanc (orthanc_process.h),
// seeded with the shared data's JPEG 2000 CT (20 slices, UIDs stamped), named
// to the server with --pacs and searched, listed and loaded over gRPC and
// from the `cinevol pacs` command. A series loads as the same volume as its
// files from the disk; names that are not the server's, URLs and bad UIDs are
// refused by name; a PACS that is down or refuses costs its caller a clear
// error in bounded time and nobody else anything.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <fstream>
#include <memory>

#include "pacs/dicomweb_client.h"
#include "pacs/loopback_http_server.h"
#include "pacs/orthanc_process.h"
#include "pacs/secondary_capture.h"
#include "pacs/stamped_series.h"
#include "service/server_process.h"
#include "service/service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

const SeriesStamp kCt{"2.25.3410001", "2.25.3410001.1", "CINEVOL-SRV-CT", "Cinevol^Server"};

class PacsServer : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    skip_ = OrthancProcess::WhatIsMissing();
    if (skip_.empty() && !fs::is_directory(SharedData())) skip_ = "the shared data are not at " + SharedData().string();
    if (!skip_.empty()) return;
    folder_ = fs::temp_directory_path() / fmt::format("cinevol-PacsServer-{}", getpid());
    fs::remove_all(folder_);
    fs::create_directories(folder_);
    orthanc_ = std::make_unique<OrthancProcess>(folder_);
    if (!orthanc_->running()) {
      failure_ = "Orthanc did not start; its log:\n" + orthanc_->Log();
      return;
    }
    const auto files = DicomFilesIn(SharedData() / "ct-body-totalsegmentator/example_ct_dicom");
    const StampedSeries ct = StampSeries(files, kCt, folder_ / "data" / "ct");
    for (const auto& instance : ct.instances) {
      if (orthanc_->Upload(instance.bytes) != 200) failure_ = "Orthanc refused an upload";
    }
    const pacs::PacsConfig config = orthanc_->Pacs();
    std::ofstream(folder_ / "pacs-credentials")
        << "# test credentials\northanc basic " << config.credentials.user << ":" << config.credentials.password
        << "\nwrong basic " << config.credentials.user << ":not-the-password\n";
  }

  static void TearDownTestSuite() {
    orthanc_.reset();  // stops it by its pid
    if (!folder_.empty()) fs::remove_all(folder_);
  }

  void SetUp() override {
    if (!skip_.empty()) GTEST_SKIP() << skip_ << "; skipping";
    ASSERT_TRUE(failure_.empty()) << failure_;
    const std::string dicom_web = orthanc_->root_url() + "/dicom-web";
    server_ = std::make_unique<ServerProcess>(
        scratch_.path(),
        std::vector<std::string>{"--data-root", (folder_ / "data").string(),  //
                                 "--pacs", "orthanc=" + dicom_web,            //
                                 "--pacs", "wrong=" + dicom_web,              // refused credentials
                                 "--pacs", fmt::format("down=http://127.0.0.1:{}/dicom-web", FreePort()),  //
                                 "--pacs-credentials", (folder_ / "pacs-credentials").string(),            //
                                 "--pacs-timeout-seconds", "10"});
    ASSERT_TRUE(server_->running()) << server_->Log();
  }

  // `cinevol ARGS --server ADDR`: its exit code and output.
  std::pair<int, std::string> Cli(std::vector<std::string> args) {
    args.insert(args.end(), {"--server", server_->address()});
    return RunProgram(CliPath(), args, scratch_ / "cli.log", 120s);
  }

  static v1::LoadSeriesRequest CtSeries() {
    v1::LoadSeriesRequest request;
    request.set_pacs("orthanc");
    request.set_study_uid(kCt.study_uid);
    request.set_series_uid(kCt.series_uid);
    return request;
  }

  static inline std::string skip_, failure_;
  static inline fs::path folder_;
  static inline std::unique_ptr<OrthancProcess> orthanc_;
  ScratchDir scratch_;
  std::unique_ptr<ServerProcess> server_;
};

TEST_F(PacsServer, TheCommandSearchesListsAndLoads) {
  Client client = server_->Connect();
  EXPECT_EQ(client.ListPacs(), (std::vector<std::string>{"orthanc", "wrong", "down"}));

  auto [code, out] = Cli({"pacs", "search", "--pacs", "orthanc", "--patient-id", kCt.patient_id});
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find(kCt.study_uid), std::string::npos) << out;
  EXPECT_NE(out.find("Cinevol^Server"), std::string::npos) << out;

  std::tie(code, out) = Cli({"pacs", "series", "--pacs", "orthanc", "--study", kCt.study_uid, "--json"});
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find(fmt::format(R"("seriesUid":"{}")", kCt.series_uid)), std::string::npos) << out;
  EXPECT_NE(out.find(R"("instanceCount":"20")"), std::string::npos) << out;

  // By patient: the latest study, its largest series.
  std::tie(code, out) = Cli({"pacs", "load", "--pacs", "orthanc", "--patient-id", kCt.patient_id, "--json"});
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find(fmt::format(R"("source":"pacs:orthanc/{}/{}")", kCt.study_uid, kCt.series_uid)), std::string::npos)
      << out;
  EXPECT_NE(out.find(R"("z":20)"), std::string::npos) << out;

  std::tie(code, out) = Cli({"pacs", "list", "--json"});
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find(R"({"names":["orthanc","wrong","down"]})"), std::string::npos) << out;

  // A session script may name a series.
  const fs::path script = scratch_ / "series.jsonl";
  std::ofstream(script)
      << fmt::format(R"({{"session": {{"series": {{"pacs": "orthanc", "studyUid": "{}", "seriesUid": "{}"}}, )"
                     R"("viewport": {{"width": 64, "height": 48}}, "stream": {{"targetSpp": 2}}}}}})",
                     kCt.study_uid, kCt.series_uid)
      << "\n";
  std::tie(code, out) =
      Cli({"play", "--script", script.string(), "--out", (scratch_ / "play").string(), "--timeout", "60"});
  EXPECT_EQ(code, 0) << out;
}

TEST_F(PacsServer, ASeriesLoadsAsTheSameVolumeAsItsFilesOnDisk) {
  Client client = server_->Connect();
  std::vector<v1::LoadSeriesProgress> progress;
  const v1::VolumeInfo from_pacs =
      client.LoadSeries(CtSeries(), [&](const v1::LoadSeriesProgress& p) { progress.push_back(p); });
  const v1::VolumeInfo from_disk = client.LoadVolume("ct");
  ASSERT_FALSE(progress.empty());
  EXPECT_EQ(progress.back().stage(), "reading");
  EXPECT_EQ(progress.back().instances_total(), 20u);
  EXPECT_GT(progress.back().bytes(), 0u);

  // Voxel for voxel: every voxel's value lands in the same histogram bin and
  // the range is the same; geometry to the bit.
  EXPECT_NE(from_pacs.id(), from_disk.id());
  EXPECT_EQ(from_pacs.dims().DebugString(), from_disk.dims().DebugString());
  EXPECT_EQ(from_pacs.spacing_mm().DebugString(), from_disk.spacing_mm().DebugString());
  EXPECT_EQ(from_pacs.origin_mm().DebugString(), from_disk.origin_mm().DebugString());
  EXPECT_EQ(from_pacs.min_value(), from_disk.min_value());
  EXPECT_EQ(from_pacs.max_value(), from_disk.max_value());
  EXPECT_EQ(from_pacs.histogram().DebugString(), from_disk.histogram().DebugString());
  EXPECT_EQ(from_pacs.modality(), "CT");
  // Who it shows, for the corners of a reading view; never in the server's log.
  EXPECT_EQ(from_pacs.identity().patient_name(), kCt.patient_name);
  EXPECT_EQ(from_pacs.identity().patient_id(), kCt.patient_id);
  EXPECT_EQ(from_disk.identity().DebugString(), from_pacs.identity().DebugString());
  EXPECT_EQ(server_->Log().find(kCt.patient_name), std::string::npos) << server_->Log();
  EXPECT_EQ(server_->Log().find(kCt.patient_id), std::string::npos) << server_->Log();

  // Held: a second load answers at once with the same volume, fetching nothing.
  progress.clear();
  const v1::VolumeInfo again =
      client.LoadSeries(CtSeries(), [&](const v1::LoadSeriesProgress& p) { progress.push_back(p); });
  EXPECT_EQ(again.id(), from_pacs.id());
  EXPECT_TRUE(progress.empty());
  // And it renders.
  v1::CreateSessionRequest session = SmallSession();
  session.set_volume_id(from_pacs.id());
  EXPECT_FALSE(client.CreateSession(session).session_id().empty());
}

// A snapshot goes back into the source's study as a Secondary Capture that a
// search finds and whose recipe reads back.
TEST_F(PacsServer, ASnapshotIsStoredBackWithItsRecipe) {
  Client client = server_->Connect();
  const v1::VolumeInfo volume = client.LoadSeries(CtSeries());
  const fs::path png = scratch_ / "render.png";
  auto [code, out] = Cli({"snapshot", "--volume", volume.id(), "--preset", "ct-bone", "--width", "64", "--height", "48",
                          "--spp", "2", "--out", png.string(), "--store-to", "orthanc"});
  ASSERT_EQ(code, 0) << out;
  const std::size_t at = out.find(", series ");
  ASSERT_NE(at, std::string::npos) << out;
  const std::string series_uid = out.substr(at + 9, out.find(',', at + 9) - at - 9);

  std::vector<v1::SeriesSummary> series = client.SearchSeries("orthanc", kCt.study_uid);
  const auto render =
      std::find_if(series.begin(), series.end(), [&](const auto& s) { return s.series_uid() == series_uid; });
  ASSERT_NE(render, series.end()) << out;
  EXPECT_EQ(render->modality(), "OT");
  EXPECT_EQ(render->description(), "cinevol render: ct-bone");

  // Its bytes, through the DICOMweb client: a cinevol render of this series.
  std::string bytes;
  pacs::RetrieveCallbacks callbacks;
  callbacks.on_instance = [&](const pacs::InstanceSummary&, std::string&& b) { bytes = std::move(b); };
  pacs::DicomWebClient(orthanc_->Pacs()).RetrieveSeries(kCt.study_uid, series_uid, callbacks);
  const pacs::ReadCapture capture = pacs::ReadSecondaryCapture(bytes);
  EXPECT_EQ(capture.source_series_uid, kCt.series_uid);
  EXPECT_EQ(capture.patient_id, kCt.patient_id);
  EXPECT_EQ(capture.preset, "ct-bone");
  EXPECT_EQ(capture.width, 64);
  EXPECT_NE(capture.scene_json.find("ct-bone"), std::string::npos) << capture.scene_json;

  // A volume from elsewhere has no study to go back to.
  std::tie(code, out) = Cli({"snapshot", "--volume", "phantom:head?size=48", "--width", "32", "--height", "32", "--spp",
                             "1", "--out", png.string(), "--store-to", "orthanc"});
  EXPECT_NE(code, 0);
  EXPECT_NE(out.find("did not come from a PACS"), std::string::npos) << out;
}

TEST_F(PacsServer, NamesThatAreNotTheServersUrlsAndBadUidsAreRefusedByName) {
  Client client = server_->Connect();
  v1::SearchStudiesRequest search;
  for (const char* name : {"nope", "http://127.0.0.1:1/dicom-web", ""}) {
    search.set_pacs(name);
    ExpectRpcError([&] { client.SearchStudies(search); }, grpc::StatusCode::INVALID_ARGUMENT, "orthanc, wrong, down");
  }
  v1::LoadSeriesRequest load = CtSeries();
  load.set_series_uid("1.2.3/../../studies");
  ExpectRpcError([&] { client.LoadSeries(load); }, grpc::StatusCode::INVALID_ARGUMENT, "series_uid");
  load = CtSeries();
  load.set_series_uid("2.25.99999");  // a UID the PACS does not hold
  ExpectRpcError([&] { client.LoadSeries(load); }, grpc::StatusCode::NOT_FOUND, "orthanc");
}

TEST_F(PacsServer, APacsThatIsDownOrRefusesIsAClearErrorAndNobodyElsesProblem) {
  Client client = server_->Connect();
  v1::SearchStudiesRequest search;
  search.set_pacs("down");
  const auto start = std::chrono::steady_clock::now();
  ExpectRpcError([&] { client.SearchStudies(search); }, grpc::StatusCode::UNAVAILABLE, "down");
  EXPECT_LT(std::chrono::steady_clock::now() - start, 30s);

  search.set_pacs("wrong");
  ExpectRpcError([&] { client.SearchStudies(search); }, grpc::StatusCode::FAILED_PRECONDITION, "wrong");

  // The server and its other callers go on.
  search.set_pacs("orthanc");
  search.set_patient_id(kCt.patient_id);
  EXPECT_EQ(client.SearchStudies(search).size(), 1u);
  EXPECT_TRUE(client.Status().accepting_sessions());
  EXPECT_EQ(server_->Log().find("not-the-password"), std::string::npos) << "a secret in the log";
}

// A PACS that lies: its listing claims a matrix past the server's limits, or
// its instances are not DICOM. Each load ends in a clear error, the first
// before any instance is fetched; the server and its other callers go on.
TEST(PacsServerHostile, ALyingPacsCostsItsCallerAnErrorAndNobodyAnythingElse) {
  ScratchDir scratch;
  const std::string kListing = "/dicom-web/studies/1.2.3/series/4.5.6/instances";
  std::atomic<int> fetched{0};
  std::atomic<bool> huge{true};
  LoopbackHttpServer pacs([&](const HttpRequestSeen& request) {
    if (request.target.rfind(kListing + "?", 0) == 0) {
      const std::string matrix = huge ? "65535" : "16";
      return Answer(200, "application/dicom+json",
                    R"([{"00080018":{"vr":"UI","Value":["4.5.6.1"]},"00280010":{"vr":"US","Value":[)" + matrix +
                        R"(]},"00280011":{"vr":"US","Value":[)" + matrix + "]}}]");
    }
    ++fetched;
    const std::string part = std::string(128, '\0') + "DICM" + std::string(64, 'x');  // DICOM only in looks
    const std::string body = "--b\r\nContent-Type: application/dicom\r\n\r\n" + part + "\r\n--b--\r\n";
    return Answer(200, "multipart/related; type=\"application/dicom\"; boundary=b", body);
  });
  ServerProcess server(scratch.path(),
                       {"--pacs", "liar=" + pacs.url() + "/dicom-web", "--max-volume-voxels", "100000000"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  v1::LoadSeriesRequest load;
  load.set_pacs("liar");
  load.set_study_uid("1.2.3");
  load.set_series_uid("4.5.6");
  ExpectRpcError([&] { client.LoadSeries(load); }, grpc::StatusCode::RESOURCE_EXHAUSTED, "max-volume-voxels");
  EXPECT_EQ(fetched.load(), 0) << "refused from the listing, before any instance came";

  huge = false;
  ExpectRpcError([&] { client.LoadSeries(load); }, grpc::StatusCode::INVALID_ARGUMENT, "pacs:liar");
  EXPECT_EQ(fetched.load(), 1);
  EXPECT_EQ(client.ListVolumes().size(), 1u) << "nothing held but the phantom";
  EXPECT_TRUE(client.Status().accepting_sessions());
  EXPECT_FALSE(client.CreateSession(SmallSession()).session_id().empty());
}

}  // namespace
}  // namespace cinevol::testing
