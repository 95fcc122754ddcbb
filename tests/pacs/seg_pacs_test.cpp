// DICOM SEG from a real PACS (issue 57): Orthanc holds the shared JPEG 2000
// CT (UIDs stamped) and a SEG written with DCMTK's dcmseg from the
// TotalSegmentator segmentation of it (cropped in-plane to where the labels
// are, in the CT's frame of reference). LoadSeries with labels_for loads the
// SEG as the CT's labels, the same as the NIfTI it came from; sessions style
// them; hostile SEGs from the PACS are refused by name, fast, within bounded
// memory, and the server goes on.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <iterator>
#include <fstream>

#include "encode/image_codecs.h"
#include "io/label_volume.h"
#include "io/volume_loader.h"
#include "pacs/measurement_requests.h"
#include "pacs/orthanc_process.h"
#include "pacs/presentation_state.h"
#include "pacs/stamped_series.h"
#include "scene/scene_file.h"
#include "service/server_process.h"
#include "service/service_test_support.h"
#include "support/seg_writer.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

const SeriesStamp kSegCt{"2.25.3430001", "2.25.3430001.1", "CINEVOL-SEG-CT", "Cinevol^SegCt"};
const std::string kSegSeries = "2.25.3430001.2";

class SegFromPacs : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    skip_ = OrthancProcess::WhatIsMissing();
    if (skip_.empty() && !fs::is_directory(SharedData())) skip_ = "the shared data are not at " + SharedData().string();
    if (!skip_.empty()) return;
    folder_ = fs::temp_directory_path() / fmt::format("cinevol-SegFromPacs-{}", getpid());
    fs::remove_all(folder_);
    fs::create_directories(folder_ / "data" / "seg");
    orthanc_ = std::make_unique<OrthancProcess>(folder_);
    if (!orthanc_->running()) {
      failure_ = "Orthanc did not start; its log:\n" + orthanc_->Log();
      return;
    }
    const fs::path shared = SharedData() / "ct-body-totalsegmentator";
    const StampedSeries ct = StampSeries(DicomFilesIn(shared / "example_ct_dicom"), kSegCt, folder_ / "data" / "ct");
    for (const auto& instance : ct.instances) {
      if (orthanc_->Upload(instance.bytes) != 200) failure_ = "Orthanc refused an upload";
    }
    // The CT as cinevol reads it, and its segmentation on its grid.
    image_ = std::make_unique<Volume>(LoadDicomSeries(folder_ / "data" / "ct"));
    const LabelVolume nifti = LoadLabelVolume(shared / "example_seg_dicom.nii.gz", *image_);
    labels_.resize(nifti.labels.size());
    for (std::size_t i = 0; i < labels_.size(); ++i) labels_[i] = std::uint16_t(nifti.LabelOf(nifti.labels[i]));
    voxels_ = nifti.voxels;
    fs::copy_file(shared / "example_seg_dicom.nii.gz", folder_ / "data" / "seg" / "example_seg_dicom.nii.gz");
    std::ifstream tsv(shared / "labels-total.tsv");
    names_ = ParseLabelTable(std::string(std::istreambuf_iterator<char>(tsv), {}), "labels-total.tsv");
    WriteSeg(folder_ / "data" / "seg" / "seg.dcm", CroppedGrid(), Options());
    if (orthanc_->Upload(ReadWholeFile(folder_ / "data" / "seg" / "seg.dcm")) != 200) {
      failure_ = "Orthanc refused the SEG";
    }
    const pacs::PacsConfig config = orthanc_->Pacs();
    std::ofstream(folder_ / "pacs-credentials")
        << "orthanc basic " << config.credentials.user << ":" << config.credentials.password << "\n";
  }

  static void TearDownTestSuite() {
    orthanc_.reset();
    image_.reset();
    if (!folder_.empty()) fs::remove_all(folder_);
  }

  void SetUp() override {
    if (!skip_.empty()) GTEST_SKIP() << skip_ << "; skipping";
    ASSERT_TRUE(failure_.empty()) << failure_;
    server_ = std::make_unique<ServerProcess>(
        scratch_.path(), std::vector<std::string>{"--data-root", (folder_ / "data").string(), "--pacs",
                                                  "orthanc=" + orthanc_->root_url() + "/dicom-web",
                                                  "--pacs-credentials", (folder_ / "pacs-credentials").string()});
    ASSERT_TRUE(server_->running()) << server_->Log();
  }

  // The labels' box in x and y, widened to whole bytes of pixels: the SEG's
  // frames cover only it (DCMTK's own binary packing then; seg_writer.h).
  static SegGrid CroppedGrid() {
    const Vec3i n = image_->dims();
    int x0 = n.x, x1 = -1, y0 = n.y, y1 = -1;
    for (int z = 0; z < n.z; ++z) {
      for (int y = 0; y < n.y; ++y) {
        for (int x = 0; x < n.x; ++x) {
          if (labels_[(std::size_t(z) * n.y + y) * n.x + x] == 0) continue;
          x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
        }
      }
    }
    const int width = std::min(n.x, (x1 - x0 + 1 + 7) / 8 * 8);
    x0 = std::min(x0, n.x - width);
    SegGrid g = AxialGrid(*image_, labels_);
    g.columns = width;
    g.rows = y1 - y0 + 1;
    const Vec3f s = image_->spacing_mm();
    for (int r = 0; r < 3; ++r) g.origin[r] += x0 * s.x * g.along_row[r] + y0 * s.y * g.down_column[r];
    std::printf("SEG frames: %dx%d of the CT's %dx%d, from (%d, %d)\n", g.columns, g.rows, n.x, n.y, x0, y0);
    g.label = [x0, y0, n](int c, int r, int k) { return int(labels_[(std::size_t(k) * n.y + y0 + r) * n.x + x0 + c]); };
    return g;
  }

  static SegOptions Options() {
    SegOptions o;
    o.segments = names_.rbegin()->first;
    o.names = names_;
    o.frame_of_reference_uid = image_->metadata().frame_of_reference_uid;
    o.study_uid = kSegCt.study_uid;
    o.series_uid = kSegSeries;
    o.sop_instance_uid = kSegSeries + ".1";
    o.patient_id = kSegCt.patient_id;
    o.patient_name = kSegCt.patient_name;
    return o;
  }

  static v1::LoadSeriesRequest Series(const std::string& series_uid, const std::string& labels_for = {}) {
    v1::LoadSeriesRequest request;
    request.set_pacs("orthanc");
    request.set_study_uid(kSegCt.study_uid);
    request.set_series_uid(series_uid);
    request.set_labels_for(labels_for);
    return request;
  }

  // Every label the NIfTI has, with as many voxels, and the SEG's names.
  static void ExpectTheNiftisLabels(const v1::LabelSet& set) {
    std::map<int, std::uint64_t> got;
    for (const v1::LabelName& n : set.names()) got[int(n.value())] = n.voxels();
    for (const auto& [label, count] : voxels_) {
      if (label == 0) continue;
      EXPECT_EQ(got[label], count) << "label " << label;
    }
  }

  static inline std::string skip_, failure_;
  static inline fs::path folder_;
  static inline std::unique_ptr<OrthancProcess> orthanc_;
  static inline std::unique_ptr<Volume> image_;
  static inline std::vector<std::uint16_t> labels_;
  static inline std::map<int, std::uint64_t> voxels_;
  static inline std::map<int, std::string> names_;
  ScratchDir scratch_;
  std::unique_ptr<ServerProcess> server_;
};

TEST_F(SegFromPacs, ASegSeriesLoadsAsTheLabelsOfTheVolumeItSegments) {
  Client client = server_->Connect();
  const v1::VolumeInfo ct = client.LoadSeries(Series(kSegCt.series_uid));
  std::vector<v1::LoadSeriesProgress> progress;
  const auto start = std::chrono::steady_clock::now();
  const v1::VolumeInfo labelled =
      client.LoadSeries(Series(kSegSeries, ct.id()), [&](const v1::LoadSeriesProgress& p) { progress.push_back(p); });
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("SEG of %ju bytes from Orthanc: %.2f s\n", std::uintmax_t(fs::file_size(folder_ / "data/seg/seg.dcm")),
              seconds);
  EXPECT_EQ(labelled.id(), ct.id());
  EXPECT_EQ(labelled.labels().source(), fmt::format("pacs:orthanc/{}/{}", kSegCt.study_uid, kSegSeries));
  EXPECT_NE(labelled.labels().note().find("DICOM SEG (BINARY, 117 segments"), std::string::npos)
      << labelled.labels().note();
  ASSERT_FALSE(progress.empty());
  EXPECT_EQ(progress.back().stage(), "reading");
  EXPECT_EQ(progress.back().instances_total(), 1u);
  ExpectTheNiftisLabels(labelled.labels());
  ASSERT_EQ(labelled.labels().names_size(), int(names_.size()) + 1);
  for (const v1::LabelName& n : labelled.labels().names()) {
    if (n.value() == 0) continue;
    EXPECT_EQ(n.name(), names_.at(int(n.value())));
    const Vec3d want = SegColor(int(n.value()));
    EXPECT_NEAR(n.color().r(), want[0], 1.5 / 255) << n.value();
    EXPECT_NEAR(n.color().b(), want[2], 1.5 / 255) << n.value();
  }
  EXPECT_EQ(client.DescribeVolume(ct.id()).labels().DebugString(), labelled.labels().DebugString());

  // The NIfTI it came from, loaded by the server from its data root, has the same labels; so has the SEG file there.
  ExpectTheNiftisLabels(client.LoadLabels(ct.id(), "seg/example_seg_dicom.nii.gz").labels());
  const v1::VolumeInfo from_disk = client.LoadLabels(ct.id(), "seg/seg.dcm");
  ExpectTheNiftisLabels(from_disk.labels());
  EXPECT_EQ(from_disk.labels().source(), "path 'seg/seg.dcm'");
  // The command: the PACS's again, each label with its name and colour; and offline, the file on the CT's files.
  auto [code, out] = RunProgram(CliPath(),
                                {"pacs", "load", "--pacs", "orthanc", "--study", kSegCt.study_uid, "--series",
                                 kSegSeries, "--labels-for", ct.id(), "--server", server_->address()},
                                scratch_ / "cli.log", 120s);
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find(fmt::format("pacs:orthanc/{}/{}", kSegCt.study_uid, kSegSeries)), std::string::npos) << out;
  const Vec3d spleen_rgb = SegColor(1);
  const std::string spleen_hex =
      fmt::format("#{:02x}{:02x}{:02x}", int(std::lround(spleen_rgb[0] * 255)), int(std::lround(spleen_rgb[1] * 255)),
                  int(std::lround(spleen_rgb[2] * 255)));
  EXPECT_NE(out.find("spleen"), std::string::npos) << out;
  EXPECT_NE(out.find(spleen_hex), std::string::npos) << spleen_hex << " in " << out;
  std::tie(code, out) = RunProgram(
      CliPath(),
      {"info", (folder_ / "data" / "ct").string(), "--labels", (folder_ / "data" / "seg" / "seg.dcm").string()},
      scratch_ / "info.log", 120s);
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find("DICOM SEG (BINARY, 117 segments"), std::string::npos) << out;

  // Sessions style its labels as any segmentation's: the liver hidden, the spleen red, the table removed.
  v1::CreateSessionRequest request = SmallSession("ct-bone");
  request.set_volume_id(ct.id());
  request.clear_preset();
  v1::Labels& labels = *request.mutable_scene()->mutable_labels();
  labels.set_remove_table(true);
  v1::LabelStyle* liver = labels.add_styles();
  liver->set_value(5);
  liver->set_visible(false);
  v1::LabelStyle* spleen = labels.add_styles();
  spleen->set_value(1);
  spleen->mutable_color()->set_r(1);
  auto stream = client.Attach(client.CreateSession(request).session_id());
  EXPECT_TRUE(WaitFrame(
      *stream, [](const v1::Frame&) { return true; }, 60s))
      << stream->status().error_message();
}

// A still of the labelled CT stored with --store-to (issue 57): its presentation state is the Segmented kind, the
// spleen shown red and the liver hidden through the SEG the labels came from. Loaded by its UID it brings back the
// series, the SEG as its labels and the styles, and renders the same still.
TEST_F(SegFromPacs, AStillsLabelStylesGoThroughTheSegInItsPresentationState) {
  Client client = server_->Connect();
  const v1::VolumeInfo ct = client.LoadSeries(Series(kSegCt.series_uid));
  client.LoadSeries(Series(kSegSeries, ct.id()));
  const fs::path scene = scratch_ / "styled.json", first = scratch_ / "first.png", again = scratch_ / "again.png",
                 presented = scratch_ / "presented.json";
  std::ofstream(scene) << R"({"transferFunction": {"preset": "ct-soft-tissue"}, "render": {"seed": 7}, "labels":)"
                       << R"( {"styles": [{"value": 1, "color": {"r": 1, "g": 0.1, "b": 0.1}}, {"value": 5, "visible": false}]}})";
  const auto cli = [&](std::vector<std::string> args) {
    args.insert(args.end(), {"--server", server_->address()});
    return RunProgram(CliPath(), args, scratch_ / "cli.log", 120s);
  };
  auto [code, out] = cli({"snapshot", "--volume", ct.id(), "--scene", scene.string(), "--width", "64", "--height",
                          "48", "--spp", "6", "--out", first.string(), "--store-to", "orthanc"});
  ASSERT_EQ(code, 0) << out;
  const std::size_t at = out.find("--presentation ");
  ASSERT_NE(at, std::string::npos) << out;
  const std::string state = out.substr(at + 15, out.find(')', at) - at - 15);
  // The Segmented kind, through the SEG: the spleen shown, the liver taken out of the image's classification.
  const pacs::DicomWebClient orthanc(orthanc_->Pacs());
  const pacs::InstanceLocation place = pacs::FindInstance(orthanc, state);
  const pacs::ReadPresentation stored =
      pacs::ReadPresentationState(pacs::RetrieveInstance(orthanc, place.study_uid, place.series_uid, state, 16 << 20));
  ASSERT_TRUE(stored.state.segmentation);
  EXPECT_EQ(stored.state.segmentation->series_uid, kSegSeries);
  EXPECT_EQ(stored.state.segmentation->styled, (std::vector<std::uint16_t>{1, 5}));
  ASSERT_EQ(stored.state.segmentation->shown.size(), 1u);
  EXPECT_EQ(stored.state.segmentation->shown[0].number, 1);
  std::tie(code, out) = cli({"pacs", "load", "--pacs", "orthanc", "--presentation", state, "--scene-out",
                             presented.string()});
  ASSERT_EQ(code, 0) << out;
  const v1::Scene shown = LoadSceneFile(presented);
  ASSERT_EQ(shown.labels().styles_size(), 2) << shown.DebugString();
  EXPECT_EQ(shown.labels().styles(0).value(), 1u);
  EXPECT_NEAR(shown.labels().styles(0).color().r(), 1, 0.01);
  EXPECT_EQ(shown.labels().styles(1).value(), 5u);
  EXPECT_FALSE(shown.labels().styles(1).visible());
  EXPECT_EQ(client.DescribeVolume(ct.id()).labels().source(),
            fmt::format("pacs:orthanc/{}/{}", kSegCt.study_uid, kSegSeries));
  std::tie(code, out) = cli({"snapshot", "--volume", ct.id(), "--scene", presented.string(), "--width", "64",
                             "--height", "48", "--spp", "6", "--out", again.string()});
  ASSERT_EQ(code, 0) << out;
  const auto read = [](const fs::path& png) {
    std::ifstream in(png, std::ios::binary);
    return DecodePng(std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), {}));
  };
  const ImageRgb8 a = read(first), b = read(again);
  double squared = 0;
  for (std::size_t i = 0; i < a.bytes.size(); ++i) squared += std::pow(double(a.bytes[i]) - double(b.bytes[i]), 2);
  const double mse = squared / double(a.bytes.size());
  const double psnr = mse == 0 ? 99 : 10 * std::log10(255.0 * 255.0 / mse);
  EXPECT_GE(psnr, 40.0) << "the labelled still rendered again from its presentation state";
  RecordProperty("psnr_db", std::to_string(psnr));
}

TEST_F(SegFromPacs, HostileSegsFromThePacsAreRefusedByNameAndTheServerGoesOn) {
  Client client = server_->Connect();
  const v1::VolumeInfo ct = client.LoadSeries(Series(kSegCt.series_uid));
  const fs::path valid = folder_ / "data" / "seg" / "seg.dcm";
  struct Case {
    std::string name, expected;
    std::function<void(DcmDataset&)> edit;
  };
  const std::vector<Case> cases = {
      {"another frame of reference", "is not the volume's (" + image_->metadata().frame_of_reference_uid + ")",
       [](DcmDataset& data) { data.putAndInsertString(DCM_FrameOfReferenceUID, "2.25.3430009"); }},
      {"frames outside", "none of its",
       [](DcmDataset& data) {
         DcmSequenceOfItems* frames = nullptr;
         data.findAndGetSequence(DCM_PerFrameFunctionalGroupsSequence, frames);
         for (unsigned long f = 0; f < frames->card(); ++f) {
           DcmItem* place = nullptr;
           frames->getItem(f)->findAndGetSequenceItem(DCM_PlanePositionSequence, place, 0);
           place->putAndInsertString(DCM_ImagePositionPatient, "0\\0\\5000");
         }
       }},
      {"ten thousand segments", "10000 segments; cinevol reads at most 1024",
       [](DcmDataset& data) {
         DcmSequenceOfItems* segments = nullptr;
         data.findAndGetSequence(DCM_SegmentSequence, segments);
         for (int s = int(segments->card()) + 1; s <= 10000; ++s) {
           auto* copy = new DcmItem(*segments->getItem(0));
           copy->putAndInsertUint16(DCM_SegmentNumber, Uint16(s));
           segments->append(copy);
         }
       }},
      {"frame counts", "Per-frame Functional Groups Sequence holds",
       [](DcmDataset& data) { data.putAndInsertString(DCM_NumberOfFrames, "7"); }},
  };
  const double resident_before = server_->ResidentMiB();
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const std::string series = fmt::format("{}.{}", kSegSeries, 10 + i);
    const fs::path file = scratch_ / fmt::format("hostile-{}.dcm", i);
    EditSeg(valid, file, [&](DcmDataset& data) {
      cases[i].edit(data);
      data.putAndInsertString(DCM_SeriesInstanceUID, series.c_str());
      data.putAndInsertString(DCM_SOPInstanceUID, (series + ".1").c_str());
    });
    ASSERT_EQ(orthanc_->Upload(ReadWholeFile(file)), 200) << cases[i].name;
    const auto start = std::chrono::steady_clock::now();
    ExpectRpcError([&] { client.LoadSeries(Series(series, ct.id())); }, grpc::StatusCode::INVALID_ARGUMENT,
                   cases[i].expected);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_LT(seconds, 20.0) << cases[i].name;
    std::printf("%-28s refused in %.2f s\n", cases[i].name.c_str(), seconds);
  }
  const double resident_after = server_->ResidentMiB();
  std::printf("server resident: %.0f MiB before, %.0f MiB after\n", resident_before, resident_after);
  EXPECT_LT(resident_after - resident_before, 64.0) << "the server's memory grew";
  // The volume keeps no half-loaded labels; the good SEG still loads; the server serves.
  EXPECT_FALSE(client.DescribeVolume(ct.id()).has_labels());
  ExpectTheNiftisLabels(client.LoadSeries(Series(kSegSeries, ct.id())).labels());
  ExpectServing(client);
}

TEST_F(SegFromPacs, LabelsForNamesAVolumeOfTheCallersAndASegSeries) {
  Client client = server_->Connect();
  ExpectRpcError([&] { client.LoadSeries(Series(kSegSeries, "no-such-volume")); }, grpc::StatusCode::NOT_FOUND,
                 "labels_for: no volume 'no-such-volume'");
  const v1::VolumeInfo ct = client.LoadSeries(Series(kSegCt.series_uid));
  ExpectRpcError([&] { client.LoadSeries(Series(kSegCt.series_uid, ct.id())); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "holds 20 instances");
  // An upload: a SEG travels as a volume's labels only.
  const fs::path seg = folder_ / "data" / "seg" / "seg.dcm";
  const v1::VolumeInfo uploaded = client.UploadLabels(ct.id(), seg);
  EXPECT_EQ(uploaded.labels().source(), "upload:seg.dcm");
  ExpectTheNiftisLabels(uploaded.labels());
  ExpectRpcError([&] { client.UploadVolume(seg); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "nor a DICOM SEG (.dcm) with header.labels_for");
  // The phantom is the operator's: only its owner or an operator may label it.
  ExpectRpcError([&] { client.LoadSeries(Series(kSegSeries, "phantom:head?size=48")); },
                 grpc::StatusCode::PERMISSION_DENIED, "labels_for");
}

}  // namespace
}  // namespace cinevol::testing
