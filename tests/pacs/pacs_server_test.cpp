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
#include <cmath>
#include <fstream>
#include <memory>
#include <thread>

#include "image_files.h"
#include "pacs/dicom_json.h"
#include "pacs/dicomweb_client.h"
#include "pacs/loopback_http_server.h"
#include "pacs/measurement_requests.h"
#include "pacs/orthanc_process.h"
#include "pacs/presentation_state.h"
#include "pacs/secondary_capture.h"
#include "pacs/stamped_series.h"
#include "scene/scene_file.h"
#include "service/server_process.h"
#include "service/service_test_support.h"
#include "support/error_of.h"
#include "support/shell_command.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

const SeriesStamp kCt{"2.25.3410001", "2.25.3410001.1", "CINEVOL-SRV-CT", "Cinevol^Server"};
// The same CT with a Pixel Spacing of 1e-10 mm: it once crashed the server (a
// table search's box radius in voxels overflowed an int).
const SeriesStamp kTinySpacing{"2.25.3410002", "2.25.3410002.1", "CINEVOL-SRV-TINY", "Cinevol^Tiny", "1e-10\\1e-10"};

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
    const StampedSeries tiny = StampSeries({files.begin(), files.begin() + 3}, kTinySpacing, folder_ / "data" / "tiny");
    for (const StampedSeries* series : {&ct, &tiny}) {
      for (const auto& instance : series->instances) {
        if (orthanc_->Upload(instance.bytes) != 200) failure_ = "Orthanc refused an upload";
      }
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
                          "--spp", "6", "--out", png.string(), "--store-to", "orthanc"});
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
  callbacks.on_instance = [&](const pacs::InstanceSummary&, const std::filesystem::path& file, std::uint64_t) {
    bytes = ReadWholeFile(file);
  };
  const ScratchDir folder;
  pacs::DicomWebClient(orthanc_->Pacs()).RetrieveSeries(kCt.study_uid, series_uid, folder.path(), callbacks);
  const pacs::ReadCapture capture = pacs::ReadSecondaryCapture(bytes);
  EXPECT_EQ(capture.source_series_uid, kCt.series_uid);
  EXPECT_EQ(capture.patient_id, kCt.patient_id);
  EXPECT_EQ(capture.preset, "ct-bone");
  EXPECT_EQ(capture.width, 64);
  EXPECT_NE(capture.scene_json.find("ct-bone"), std::string::npos) << capture.scene_json;
  // The still's samples, not the session's per frame; in patient coordinates.
  EXPECT_NE(capture.scene_json.find("\"spp\":6"), std::string::npos) << capture.scene_json;
  EXPECT_NE(capture.scene_json.find("\"frame\":\"PATIENT_LPS\""), std::string::npos) << capture.scene_json;

  // A volume from elsewhere has no study to go back to.
  std::tie(code, out) = Cli({"snapshot", "--volume", "phantom:head?size=48", "--width", "32", "--height", "32", "--spp",
                             "1", "--out", png.string(), "--store-to", "orthanc"});
  EXPECT_NE(code, 0);
  EXPECT_NE(out.find("did not come from a PACS"), std::string::npos) << out;
}

// PSNR (dB) of two 8-bit RGB pictures of one size.
double Psnr8(const RgbImage& a, const RgbImage& b) {
  double squared = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) squared += std::pow(double(a.rgb[i]) - double(b.rgb[i]), 2);
  const double mse = squared / double(a.rgb.size());
  return mse == 0 ? 99.0 : 10 * std::log10(255.0 * 255.0 / mse);
}

// "KEY VALUE," after `key` in a command's output.
std::string Word(const std::string& out, const std::string& key) {
  const std::size_t at = out.find(key);
  if (at == std::string::npos) return {};
  const std::size_t start = at + key.size();
  return out.substr(start, out.find_first_of(" ,)\n", start) - start);
}

// A still stored with --store-to has a Volume Rendering Volumetric Presentation State beside it, in a PR series of
// the study: loaded by its UID alone, it loads the series and gives back the scene, which renders the same still.
TEST_F(PacsServer, APresentationStateBesideTheStillRendersItAgain) {
  Client client = server_->Connect();
  const v1::VolumeInfo volume = client.LoadSeries(CtSeries());
  // A crop box (the middle of the CT across, all of it down and along) and a capped clip plane through its centre,
  // so the cropping goes through the standard's attributes too.
  const v1::Vec3& origin = volume.origin_mm();
  const double extent[3] = {volume.dims().x() * volume.spacing_mm().x(), volume.dims().y() * volume.spacing_mm().y(),
                            volume.dims().z() * volume.spacing_mm().z()};
  const double center[3] = {origin.x() + extent[0] / 2, origin.y() + extent[1] / 2, origin.z() + extent[2] / 2};
  const fs::path scene_file = scratch_ / "cropped.json";
  std::ofstream(scene_file) << fmt::format(
      R"({{"transferFunction": {{"preset": "ct-bone"}}, "clipping": {{"cropBox": {{)"
      R"("center": {{"x": {}, "y": {}, "z": {}}}, "size": {{"x": {}, "y": {}, "z": {}}}}},)"
      R"("planes": [{{"point": {{"x": {}, "y": 0, "z": 0}}, "normal": {{"x": -1, "y": 0, "z": 0}}, "cap": true}}]}},)"
      R"("render": {{"seed": 7}}}})",
      center[0], center[1], center[2], extent[0] * 0.6, extent[1] * 2, extent[2] * 2, center[0] + 20);
  const fs::path first = scratch_ / "first.png", again = scratch_ / "again.png";
  auto [code, out] = Cli({"snapshot", "--volume", volume.id(), "--scene", scene_file.string(), "--width", "64",
                          "--height", "48", "--spp", "6", "--out", first.string(), "--store-to", "orthanc"});
  ASSERT_EQ(code, 0) << out;
  const std::string state_uid = Word(out, "--presentation ");
  ASSERT_TRUE(pacs::IsValidUid(state_uid)) << out;
  const std::vector<v1::SeriesSummary> series = client.SearchSeries("orthanc", kCt.study_uid);
  EXPECT_TRUE(std::any_of(series.begin(), series.end(), [](const v1::SeriesSummary& s) {
    return s.modality() == "PR" && s.description() == "cinevol presentation";
  }));

  // By its UID alone: the series it presents, loaded, and its scene in a file.
  const fs::path presented = scratch_ / "presented.json";
  std::tie(code, out) =
      Cli({"pacs", "load", "--pacs", "orthanc", "--presentation", state_uid, "--scene-out", presented.string()});
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find(volume.id()), std::string::npos) << out;  // the same series: the volume already held
  EXPECT_NE(out.find("presentation state CINEVOL_RENDER: cinevol render: ct-bone"), std::string::npos) << out;
  const std::string scene_json = ReadWholeFile(presented);
  EXPECT_NE(scene_json.find("\"cap\": true"), std::string::npos) << scene_json;
  std::tie(code, out) = Cli({"snapshot", "--volume", volume.id(), "--scene", presented.string(), "--width", "64",
                             "--height", "48", "--spp", "6", "--out", again.string()});
  ASSERT_EQ(code, 0) << out;
  const RgbImage stored = DecodePngImage(ReadWholeFile(first));
  std::size_t shown = 0;  // pixels of the CT, not the background (the top left corner's)
  for (std::size_t i = 0; i < stored.rgb.size(); i += 3)
    shown += std::abs(int(stored.rgb[i]) - int(stored.rgb[0])) > 10;
  EXPECT_GT(shown, stored.rgb.size() / 3 / 20) << "the still shows the CT";
  const double psnr = Psnr8(stored, DecodePngImage(ReadWholeFile(again)));
  EXPECT_GE(psnr, 40.0) << "the still rendered again from its presentation state";
  RecordProperty("psnr_db", std::to_string(psnr));

  // As another system would hold it: without cinevol's private block (DCMTK's dcmodify takes it out and gives the
  // copy its own UID), the standard's attributes alone render nearly the same picture: the view, the crop, the
  // colours, the extinctions and the shading's materials; not the gradient factor, the cap or per-point materials,
  // which only cinevol's recipe says (34 dB here, docs/pacs.md).
  ASSERT_TRUE(Installed("dcmodify")) << "dcmodify (DCMTK) is not installed: run scripts/install-deps.sh";
  const pacs::DicomWebClient orthanc(orthanc_->Pacs());
  const pacs::InstanceLocation place = pacs::FindInstance(orthanc, state_uid);
  const fs::path copy = scratch_ / "foreign.dcm";
  WriteFile(copy, pacs::RetrieveInstance(orthanc, place.study_uid, place.series_uid, state_uid, 16 << 20));
  const CommandResult stripped =
      RunCommand("dcmodify -nb -ea '(0041,1001)' -ea '(0041,0010)' -gin '" + copy.string() + "'");
  ASSERT_EQ(stripped.status, 0) << stripped.output;
  const std::string foreign = ReadWholeFile(copy);
  ASSERT_EQ(foreign.find("CINEVOL RECIPE"), std::string::npos);
  orthanc.StoreInstances(place.study_uid, {foreign});
  const std::string foreign_uid = pacs::ReadPresentationState(foreign).uids.sop_instance_uid;
  std::tie(code, out) =
      Cli({"pacs", "load", "--pacs", "orthanc", "--presentation", foreign_uid, "--scene-out", presented.string()});
  ASSERT_EQ(code, 0) << out;
  v1::Scene standard_scene = LoadSceneFile(presented);  // the same seed, which only the recipe says
  EXPECT_EQ(standard_scene.render().seed(), 0u);
  standard_scene.mutable_render()->set_seed(7);
  SaveSceneFile(standard_scene, presented);
  std::tie(code, out) = Cli({"snapshot", "--volume", volume.id(), "--scene", presented.string(), "--width", "64",
                             "--height", "48", "--spp", "6", "--out", again.string()});
  ASSERT_EQ(code, 0) << out;
  const double standard_psnr = Psnr8(stored, DecodePngImage(ReadWholeFile(again)));
  EXPECT_GE(standard_psnr, 30.0) << "the still rendered from the standard's attributes alone";
  RecordProperty("standard_only_psnr_db", std::to_string(standard_psnr));

  // A presentation state naming a series the PACS does not hold: refused by name, and the server serves on.
  const char* kAbsentSeries = "2.25.404404404";
  const CommandResult renamed = RunCommand("dcmodify -nb -gin -m '(0008,1115)[0].(0020,000e)=" +
                                           std::string(kAbsentSeries) + "' '" + copy.string() + "'");
  ASSERT_EQ(renamed.status, 0) << renamed.output;
  const std::string orphan = ReadWholeFile(copy);
  orthanc.StoreInstances(place.study_uid, {orphan});
  const std::string orphan_uid = pacs::ReadPresentationState(orphan).uids.sop_instance_uid;
  std::tie(code, out) =
      Cli({"pacs", "load", "--pacs", "orthanc", "--presentation", orphan_uid, "--scene-out", presented.string()});
  EXPECT_NE(code, 0) << out;
  EXPECT_NE(out.find(kAbsentSeries), std::string::npos) << "the refusal names the series: " << out;
  EXPECT_EQ(client.LoadSeries(CtSeries()).id(), volume.id()) << "the server serves on";
}

// A movie goes back into the study as DICOM video (issue 58): a Multi-frame True Color Secondary Capture in the
// MPEG-4 AVC/H.264 transfer syntax that dciodvfy finds no error in and FFmpeg plays with every frame.
TEST_F(PacsServer, AMovieIsStoredAsDicomVideoThatValidatesAndPlays) {
  ASSERT_TRUE(Installed("dciodvfy") && Installed("ffprobe")) << "run scripts/install-deps.sh";
  Client client = server_->Connect();
  const v1::VolumeInfo volume = client.LoadSeries(CtSeries());
  const fs::path movie = scratch_ / "orbit.mp4";
  auto [code, out] = Cli({"movie",     "--volume", volume.id(), "--preset", "ct-bone",      "--orbit",    "90",
                          "--seconds", "0.4",      "--fps",     "10",       "--width",      "64",         "--height",
                          "48",        "--spp",    "2",         "--out",    movie.string(), "--store-to", "orthanc"});
  ASSERT_EQ(code, 0) << out << server_->Log();
  const std::string series_uid = Word(out, "stored in PACS 'orthanc': study " + kCt.study_uid + ", series ");
  const std::string instance_uid = Word(out, ", instance ");
  ASSERT_TRUE(pacs::IsValidUid(series_uid) && pacs::IsValidUid(instance_uid)) << out;
  const std::vector<v1::SeriesSummary> series = client.SearchSeries("orthanc", kCt.study_uid);
  EXPECT_TRUE(std::any_of(series.begin(), series.end(), [&](const v1::SeriesSummary& s) {
    return s.series_uid() == series_uid && s.modality() == "OT" && s.description() == "cinevol movie: orbit 90 deg";
  }));

  const fs::path stored = scratch_ / "movie.dcm";
  WriteFile(stored, pacs::RetrieveInstance(pacs::DicomWebClient(orthanc_->Pacs()), kCt.study_uid, series_uid,
                                           instance_uid, 16 << 20));
  const CommandResult checked = RunCommand("dciodvfy '" + stored.string() + "'");
  EXPECT_NE(checked.output.find("MultiframeTrueColorSCImage"), std::string::npos) << checked.output;
  std::istringstream lines(checked.output);
  for (std::string line; std::getline(lines, line);) {
    EXPECT_EQ(line.find("Error"), std::string::npos) << checked.output;
    if (line.find("Warning") != std::string::npos && line.find("DICOMDIR") == std::string::npos) {
      EXPECT_NE(line.find("<Laterality>"), std::string::npos) << "a warning not in docs/pacs.md: " << line;
    }
  }
  const CommandResult probed = RunCommand(
      "ffprobe -v error -count_frames -select_streams v:0 -show_entries "
      "stream=codec_name,width,height,nb_read_frames -of default=nw=1 '" +
      stored.string() + "'");
  for (const char* expected : {"codec_name=h264", "width=64", "height=48", "nb_read_frames=4"}) {
    EXPECT_NE(probed.output.find(expected), std::string::npos) << expected << "\n" << probed.output;
  }

  // A movie of a volume from elsewhere has no study to go into: said before a frame is rendered.
  std::tie(code, out) =
      Cli({"movie", "--volume", "phantom:head?size=48", "--orbit", "90", "--seconds", "0.2", "--fps", "10", "--width",
           "32", "--height", "32", "--spp", "1", "--out", movie.string(), "--store-to", "orthanc"});
  EXPECT_NE(code, 0);
  EXPECT_NE(out.find("did not come from a PACS"), std::string::npos) << out;
  // Beyond what DICOM's H.264 level holds: refused before a still is rendered.
  std::tie(code, out) = Cli({"movie", "--volume", volume.id(), "--orbit", "90", "--fps", "60", "--out", movie.string(),
                             "--store-to", "orthanc"});
  EXPECT_NE(code, 0);
  EXPECT_NE(out.find("at most 1920x1080 at 30 frames/s"), std::string::npos) << out;
  // A refused movie leaves no file behind (the MP4 was open when DICOM's level refused the rate).
  EXPECT_TRUE(TemporaryFilesNamed(fmt::format("cinevol-movie-{}-", server_->pid())).empty());
}

// What RenderMovie cannot make or store is refused by name before a frame renders: no such session, an unknown
// PACS, no path, a sweep across no patient axis, a cost over --max-movie-samples.
TEST_F(PacsServer, AMovieThatCannotBeMadeIsRefusedByName) {
  Client client = server_->Connect();
  v1::CreateSessionRequest request = SmallSession();
  request.set_volume_id(client.LoadSeries(CtSeries()).id());
  v1::MovieRequest movie;
  movie.set_session_id(client.CreateSession(request).session_id());
  movie.set_orbit_degrees(90);
  movie.set_seconds(0.4);
  movie.set_fps(10);
  v1::MovieRequest nowhere = movie;
  nowhere.set_store_to("nope");
  ExpectRpcError([&] { client.RenderMovie(nowhere); }, grpc::StatusCode::INVALID_ARGUMENT, "store_to");
  v1::MovieRequest nobody = movie;
  nobody.set_session_id("no-such-session");
  ExpectRpcError([&] { client.RenderMovie(nobody); }, grpc::StatusCode::NOT_FOUND, "no-such-session");
  v1::MovieRequest pathless = movie;
  pathless.clear_orbit_degrees();
  ExpectRpcError([&] { client.RenderMovie(pathless); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "give orbit_degrees, sweep or phases");
  v1::MovieRequest oblique = movie;
  oblique.set_sweep(v1::OBLIQUE);
  ExpectRpcError([&] { client.RenderMovie(oblique); }, grpc::StatusCode::INVALID_ARGUMENT, "sweep");
  v1::MovieRequest costly = movie;
  costly.set_seconds(120);
  costly.set_fps(30);
  costly.set_spp(16384);
  ExpectRpcError([&] { client.RenderMovie(costly); }, grpc::StatusCode::INVALID_ARGUMENT, "--max-movie-samples");
  EXPECT_TRUE(client.Status().accepting_sessions());
}

// A rendered frame (Supplement 174) of an image of a loaded series lies on
// that image's own plane and pixel grid, from the PACS's metadata: the same
// pixels as the axial slice through the volume there. What it cannot render
// is refused by name.
TEST_F(PacsServer, AFrameOfAnImageRendersOnItsOwnPlaneAndGrid) {
  Client client = server_->Connect();
  v1::RenderFrameRequest frame;
  frame.set_pacs("orthanc");
  frame.set_study_uid(kCt.study_uid);
  frame.set_series_uid(kCt.series_uid);
  frame.set_sop_instance_uid(kCt.series_uid + ".7");
  frame.set_window(400);
  frame.set_level(40);
  ExpectRpcError([&] { client.RenderFrame(frame); }, grpc::StatusCode::FAILED_PRECONDITION, "LoadSeries it first");

  const v1::VolumeInfo volume = client.LoadSeries(CtSeries());
  const v1::SliceImage image = client.RenderFrame(frame);
  EXPECT_EQ(image.width(), volume.dims().x());
  EXPECT_EQ(image.height(), volume.dims().y());
  EXPECT_FLOAT_EQ(image.row_spacing_mm(), volume.spacing_mm().x());
  v1::CreateSessionRequest session = SmallSession();
  session.set_volume_id(volume.id());
  v1::SliceRequest axial;
  axial.set_session_id(client.CreateSession(session).session_id());
  axial.set_axis(v1::AXIAL);
  axial.set_position_mm(image.origin_mm().z());
  axial.set_window(400);
  axial.set_level(40);
  axial.set_hide_labels(true);
  const v1::SliceImage slice = client.RenderSlice(axial);
  EXPECT_EQ(slice.origin_mm().DebugString(), image.origin_mm().DebugString());
  const RgbImage from_frame = DecodePngImage(image.png()), from_slice = DecodePngImage(slice.png());
  ASSERT_EQ(from_frame.rgb.size(), from_slice.rgb.size());
  int most_apart = 0;
  for (std::size_t i = 0; i < from_frame.rgb.size(); ++i) {
    most_apart = std::max(most_apart, std::abs(int(from_frame.rgb[i]) - int(from_slice.rgb[i])));
  }
  EXPECT_LE(most_apart, 1) << "grey levels apart";
  EXPECT_GT(*std::max_element(from_frame.rgb.begin(), from_frame.rgb.end()), 200) << "the body shows";

  // In a viewport: the frame's square field in square pixels, the viewport's shorter side.
  v1::RenderFrameRequest small = frame;
  small.mutable_viewport()->set_width(100);
  small.mutable_viewport()->set_height(60);
  const v1::SliceImage fitted = client.RenderFrame(small);
  EXPECT_EQ(fitted.height(), 60u);
  EXPECT_NEAR(double(fitted.width()),
              60.0 * volume.dims().x() * volume.spacing_mm().x() / (volume.dims().y() * volume.spacing_mm().y()), 1.0);

  v1::RenderFrameRequest second = frame;
  second.set_frame(2);
  ExpectRpcError([&] { client.RenderFrame(second); }, grpc::StatusCode::NOT_FOUND, "frame 2 is not one of them");
  v1::RenderFrameRequest missing = frame;
  missing.set_sop_instance_uid(kCt.series_uid + ".99");
  ExpectRpcError([&] { client.RenderFrame(missing); }, grpc::StatusCode::NOT_FOUND, "orthanc");
  v1::RenderFrameRequest path = frame;
  path.set_sop_instance_uid("1.2/../../studies");
  ExpectRpcError([&] { client.RenderFrame(path); }, grpc::StatusCode::INVALID_ARGUMENT, "sop_instance_uid");
  v1::RenderFrameRequest huge = frame;
  huge.mutable_viewport()->set_width(1000000);
  ExpectRpcError([&] { client.RenderFrame(huge); }, grpc::StatusCode::INVALID_ARGUMENT, "viewport");
  EXPECT_TRUE(client.Status().accepting_sessions());
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

// A Pixel Spacing of 1e-10 mm, from a data root or from the PACS: refused by
// name when the geometry is checked, and the server goes on.
TEST_F(PacsServer, ATinySpacingIsRefusedByNameFromDiskAndFromThePacs) {
  Client client = server_->Connect();
  ExpectRpcError([&] { client.LoadVolume("tiny"); }, grpc::StatusCode::INVALID_ARGUMENT, "spacing");
  v1::LoadSeriesRequest request = CtSeries();
  request.set_study_uid(kTinySpacing.study_uid);
  request.set_series_uid(kTinySpacing.series_uid);
  ExpectRpcError([&] { client.LoadSeries(request); }, grpc::StatusCode::INVALID_ARGUMENT, "outside [0.0001, 10000]");
  ExpectServing(client);
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

// What a hostile PACS answers a search with: an array that hides 100,000
// levels of nesting behind a single-quoted string (which a lenient parser
// takes and a depth check that knows only double quotes skips), and 16 MiB of
// empty arrays. Each costs its caller a clear error within seconds and the
// server a bounded amount of memory; a neighbour's stream goes on.
TEST(PacsServerHostile, SearchAnswersThatHideDepthOrSwellAreRefusedFast) {
  ScratchDir scratch;
  const std::string hidden = "['\"', " + std::string(100000, '[') + std::string(100000, ']') + "]";
  std::string swollen = "[";
  while (swollen.size() < (std::size_t{16} << 20) - 8) swollen += "[],";
  swollen += "[]]";
  std::atomic<int> asked{0};
  LoopbackHttpServer pacs([&](const HttpRequestSeen&) {
    return Answer(200, "application/dicom+json", asked++ % 2 == 0 ? hidden : swollen);
  });
  ServerProcess server(scratch.path(), {"--pacs", "hostile=" + pacs.url() + "/dicom-web"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto neighbour = client.CreateSession(SmallSession("ct-bone", 96, 64, 65536));
  auto stream = client.Attach(neighbour.session_id());
  ASSERT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }));
  const double resident_before = server.ResidentMiB();
  Witness witness(*stream);
  v1::SearchStudiesRequest search;
  search.set_pacs("hostile");
  for (const char* expected : {"not JSON: a value expected, not '''", "more than 1048576 values"}) {
    const auto start = std::chrono::steady_clock::now();
    ExpectRpcError([&] { client.SearchStudies(search); }, grpc::StatusCode::FAILED_PRECONDITION, expected);
    EXPECT_LT(std::chrono::steady_clock::now() - start, 10s) << expected;
  }
  const Witness::Report seen = witness.Stop();
  EXPECT_LT(server.ResidentMiB() - resident_before, 256.0) << "a 16 MiB answer cost this much memory";
  EXPECT_LT(seen.longest_gap_s, 1.0) << "the neighbour's stream stopped";
  ExpectServing(client);
}

// A PACS whose instance answers never end: the bodies stream to disk as they
// come, counted against --pacs-max-series-mb, so the load ends with that limit
// named and the server's memory stays where it was.
TEST(PacsServerHostile, EndlessInstanceBodiesCostDiskWithinTheLimitNotMemory) {
  ScratchDir scratch;
  const std::string kListing = "/dicom-web/studies/1.2.3/series/4.5.6/instances";
  LoopbackHttpServer pacs([&](const HttpRequestSeen& request) {
    if (request.target.rfind(kListing + "?", 0) == 0) {
      std::string json = "[";
      for (int i = 1; i <= 4; ++i) {
        json +=
            fmt::format(R"({}{{"00080018":{{"vr":"UI","Value":["4.5.6.{}"]}},"00280010":{{"vr":"US","Value":[16]}},)"
                        R"("00280011":{{"vr":"US","Value":[16]}}}})",
                        i > 1 ? "," : "", i);
      }
      return Answer(200, "application/dicom+json", json + "]");
    }
    HttpAnswer endless;  // no Content-Length: the cap can only be kept as the bytes come
    endless.head =
        "HTTP/1.1 200 OK\r\nContent-Type: multipart/related; type=\"application/dicom\"; boundary=b\r\n"
        "Connection: close\r\n\r\n";
    endless.body = "--b\r\nContent-Type: application/dicom\r\n\r\n" + std::string(128, '\0') + "DICM";
    endless.filler_bytes = std::size_t{1} << 30;
    return endless;
  });
  ServerProcess server(scratch.path(), {"--pacs", "endless=" + pacs.url() + "/dicom-web", "--pacs-max-series-mb", "256",
                                        "--pacs-timeout-seconds", "60"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const double resident_before = server.ResidentMiB();
  std::atomic<bool> done{false};
  double resident_most = resident_before;
  std::thread sampler([&] {
    for (int i = 0; i < 6000 && !done; ++i) {
      resident_most = std::max(resident_most, server.ResidentMiB());
      std::this_thread::sleep_for(10ms);
    }
  });
  v1::LoadSeriesRequest load;
  load.set_pacs("endless");
  load.set_study_uid("1.2.3");
  load.set_series_uid("4.5.6");
  ExpectRpcError([&] { client.LoadSeries(load); }, grpc::StatusCode::INVALID_ARGUMENT, "(max_series_bytes)");
  done = true;
  sampler.join();
  EXPECT_LT(resident_most - resident_before, 64.0) << "256 MiB of instance bodies went through memory";
  EXPECT_GE(pacs.bytes_sent(), std::size_t{200} << 20) << "the bodies did come";
  ExpectServing(client);
}

// Searches of a PACS that stalls hold at most half the server's PACS slots,
// and one caller's loads from it at most half its loaders: another caller's
// search of a healthy PACS and upload go on at once.
TEST(PacsServerHostile, AStalledPacsHoldsOnlyItsShare) {
  ScratchDir scratch;
  LoopbackHttpServer stalled([](const HttpRequestSeen& request) {
    HttpAnswer answer = Answer(200, "application/dicom+json",
                               request.target.find("/instances?") != std::string::npos
                                   ? R"([{"00080018":{"vr":"UI","Value":["4.5.6.1"]}}])"
                                   : "[]");
    if (request.target.find("/instances?") == std::string::npos) answer.delay = 25s;  // cut short when it stops
    return answer;
  });
  LoopbackHttpServer healthy([](const HttpRequestSeen&) { return Answer(200, "application/dicom+json", "[]"); });
  std::ofstream(scratch / "tokens") << "alice-token alice\nbob-token bob\n";
  WriteSmallNrrd(scratch / "small.nrrd");
  ServerProcess server(
      scratch.path(),
      {"--auth-tokens", (scratch / "tokens").string(), "--pacs", "stalled=" + stalled.url() + "/dicom-web", "--pacs",
       "healthy=" + healthy.url() + "/dicom-web", "--pacs-timeout-seconds", "30", "--max-uploads-per-principal", "8"});
  ASSERT_TRUE(server.running()) << server.Log();
  std::vector<std::thread> alice;
  for (int i = 0; i < 4; ++i) {
    alice.emplace_back([&, i] {
      Client client = server.Connect("alice-token");
      try {
        if (i % 2 == 0) {
          v1::SearchStudiesRequest search;
          search.set_pacs("stalled");
          client.SearchStudies(search);
        } else {
          v1::LoadSeriesRequest load;
          load.set_pacs("stalled");
          load.set_study_uid("1.2.3");
          load.set_series_uid("4.5.6");
          client.LoadSeries(load);
        }
      } catch (const std::exception&) {  // the stalled PACS's time-outs, or the server's end
      }
    });
  }
  std::this_thread::sleep_for(1s);  // alice's calls are in
  Client bob = server.Connect("bob-token");
  v1::SearchStudiesRequest search;
  search.set_pacs("healthy");
  auto start = std::chrono::steady_clock::now();
  EXPECT_TRUE(bob.SearchStudies(search).empty());
  EXPECT_LT(std::chrono::steady_clock::now() - start, 5s) << "bob's search waited on alice's stalled PACS";
  start = std::chrono::steady_clock::now();
  EXPECT_FALSE(bob.UploadVolume(scratch / "small.nrrd").id().empty());
  EXPECT_LT(std::chrono::steady_clock::now() - start, 5s) << "bob's upload waited on alice's loads";
  server.Stop();  // ends alice's calls
  for (std::thread& t : alice) t.join();
}

// --pacs-auth forward: the PACS sees each caller's own token, never the
// server's; a call without one is refused naming the flag; without a token
// file each token is its own principal; the server never logs a token.
TEST(PacsServerHostile, ForwardedTokensReachThePacsAndNameTheirCallers) {
  ScratchDir scratch;
  LoopbackHttpServer pacs([](const HttpRequestSeen& request) {
    const bool alice = request.head.find("Authorization: Bearer alice.oidc-token==") != std::string::npos;
    return alice ? Answer(200, "application/dicom+json", R"([{"0020000D":{"vr":"UI","Value":["1.2.3"]}}])")
                 : Answer(401, "text/plain", "who are you?");
  });
  ServerProcess server(scratch.path(), {"--pacs", "gated=" + pacs.url() + "/dicom-web", "--pacs-auth", "forward"});
  ASSERT_TRUE(server.running()) << server.Log();
  v1::SearchStudiesRequest search;
  search.set_pacs("gated");
  EXPECT_EQ(server.Connect("alice.oidc-token==").SearchStudies(search).size(), 1u) << "alice's own token";
  const std::string refused = ErrorOf<std::exception>([&] { server.Connect("mallory-token").SearchStudies(search); });
  EXPECT_NE(refused.find("refused the caller's token"), std::string::npos) << refused;
  const std::string tokenless = ErrorOf<std::exception>([&] { server.Connect().SearchStudies(search); });
  EXPECT_NE(tokenless.find("--pacs-auth forward"), std::string::npos) << tokenless;
  const std::string header =
      ErrorOf<std::exception>([&] { server.Connect("evil; X-Injected: 1").SearchStudies(search); });
  EXPECT_NE(header.find("RFC 6750"), std::string::npos) << "a token that is no RFC 6750 token never reaches a header";
  for (const HttpRequestSeen& seen : pacs.requests()) {
    EXPECT_EQ(seen.head.find("X-Injected"), std::string::npos) << seen.head;
  }

  // Each token its own principal: alice's upload is not mallory's to see.
  WriteSmallNrrd(scratch / "small.nrrd");
  const std::string id = server.Connect("alice.oidc-token==").UploadVolume(scratch / "small.nrrd").id();
  const std::string hidden = ErrorOf<std::exception>([&] { server.Connect("mallory-token").DescribeVolume(id); });
  EXPECT_FALSE(hidden.empty()) << "another token's caller saw alice's volume";
  server.Stop();
  EXPECT_EQ(server.Log().find("oidc-token"), std::string::npos) << "a token reached the log";
}

// `cinevol pacs search` prints what a PACS names a patient: an escape
// sequence or a carriage return in it reaches the terminal as text.
TEST(PacsServerHostile, ControlCharactersInNamesAreEscapedOnTheTerminal) {
  ScratchDir scratch;
  LoopbackHttpServer pacs([](const HttpRequestSeen&) {
    return Answer(200, "application/dicom+json",
                  R"([{"0020000D":{"vr":"UI","Value":["1.2.3"]},"00100010":{"vr":"PN","Value":[{"Alphabetic":)"
                  R"("EVIL\u001b[2J\rDOE\u009b1m"}]}}])");
  });
  ServerProcess server(scratch.path(), {"--pacs", "hostile=" + pacs.url() + "/dicom-web"});
  ASSERT_TRUE(server.running()) << server.Log();
  const auto [code, out] = RunProgram(CliPath(), {"pacs", "search", "--pacs", "hostile", "--server", server.address()},
                                      scratch / "cli.log", 60s);
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find("EVIL\\x1b[2J\\x0dDOE\\xc2\\x9b1m"), std::string::npos) << out;
  EXPECT_EQ(out.find('\x1b'), std::string::npos) << "a raw escape reached the terminal";
  EXPECT_EQ(out.find('\r'), std::string::npos);
}

}  // namespace
}  // namespace cinevol::testing
