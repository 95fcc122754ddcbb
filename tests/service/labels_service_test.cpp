// Segmentations through the API, over real gRPC to a real server: upload and
// load a label volume for a volume, read its names, style its labels by
// event; and the errors that name what is wrong (issue 22).
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <fstream>

#include "image_metrics.h"
#include "server_process.h"
#include "service_test_support.h"
#include "support/patient_on_table.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

constexpr int kSize = 32;

// A 32^3 NRRD of 16-bit values, 1 mm voxels: `value(x, y, z)`.
void WriteNrrd(const std::filesystem::path& file, const std::function<int(int, int, int)>& value) {
  std::ofstream out(file, std::ios::binary);
  out << "NRRD0004\ntype: unsigned short\ndimension: 3\nsizes: 32 32 32\nspacings: 1 1 1\nencoding: raw\n"
         "endian: little\n\n";
  for (int z = 0; z < kSize; ++z)
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        const std::uint16_t v = static_cast<std::uint16_t>(value(x, y, z));
        out.write(reinterpret_cast<const char*>(&v), 2);
      }
}

class LabelsOverTheApi : public ::testing::Test {
 protected:
  void SetUp() override {
    // A block of 2000 in 0; labels: 1 on the left half, 2 on the right.
    WriteNrrd(scratch_ / "block.nrrd", [](int x, int y, int z) {
      const auto inside = [](int i) { return i >= 8 && i < 24; };
      return inside(x) && inside(y) && inside(z) ? 2000 : 0;
    });
    WriteNrrd(scratch_ / "halves.nrrd", [](int x, int, int) { return x < kSize / 2 ? 1 : 2; });
    std::ofstream(scratch_ / "halves.tsv") << "# value\tname\n1\tleft half\n2\tright half\n";
    server_ = std::make_unique<ServerProcess>(scratch_.path(),
                                              std::vector<std::string>{"--data-root", scratch_.path().string()});
    ASSERT_TRUE(server_->running()) << server_->Log();
  }

  ScratchDir scratch_;
  std::unique_ptr<ServerProcess> server_;
};

TEST_F(LabelsOverTheApi, AnUploadedSegmentationIsNamedAndItsLabelsHideByEvent) {
  Client client = server_->Connect();
  const v1::VolumeInfo block = client.UploadVolume(scratch_ / "block.nrrd");
  const v1::VolumeInfo labelled = client.UploadLabels(block.id(), scratch_ / "halves.nrrd", scratch_ / "halves.tsv");
  ASSERT_EQ(labelled.labels().names_size(), 2);
  EXPECT_EQ(labelled.labels().names(0).name(), "left half");
  EXPECT_EQ(labelled.labels().names(1).voxels(), std::uint64_t(kSize) * kSize * kSize / 2);
  EXPECT_EQ(client.DescribeVolume(block.id()).labels().names(1).name(), "right half");

  v1::CreateSessionRequest request = SmallSession("ct-bone");
  request.set_volume_id(block.id());
  auto stream = client.Attach(client.CreateSession(request).session_id());
  const auto whole = WaitFinal(*stream);
  ASSERT_TRUE(whole) << stream->status().error_message();
  v1::SessionEvent hide;
  for (int label : {1, 2}) {
    v1::LabelStyle* style = hide.mutable_labels()->add_styles();
    style->set_value(label);
    style->set_visible(false);
  }
  const auto hidden = WaitFinal(*stream, stream->Send(hide));
  ASSERT_TRUE(hidden);
  v1::SessionEvent show;
  show.mutable_labels();
  const auto back = WaitFinal(*stream, stream->Send(show));
  ASSERT_TRUE(back);
  const auto psnr = [](const v1::Frame& x, const v1::Frame& y) {
    const RgbImage a = DecodeFrame(x), b = DecodeFrame(y);
    return Psnr(ImageRgb8{a.width, a.height, a.rgb}, ImageRgb8{b.width, b.height, b.rgb});
  };
  EXPECT_LT(psnr(*whole, *hidden), 20.0) << "hiding both labels hides the block";
  EXPECT_GT(psnr(*whole, *back), 30.0) << "showing them brings it back";
}

TEST_F(LabelsOverTheApi, ASegmentationLoadsFromTheDataRootsOnly) {
  Client client = server_->Connect();
  const v1::VolumeInfo block = client.LoadVolume("block.nrrd");
  const v1::VolumeInfo labelled = client.LoadLabels(block.id(), "halves.nrrd", "halves.tsv");
  EXPECT_EQ(labelled.labels().names(0).name(), "left half");
  ExpectRpcError([&] { client.LoadLabels(block.id(), "/etc/passwd"); }, grpc::StatusCode::PERMISSION_DENIED, "path");
  ExpectRpcError([&] { client.LoadLabels(block.id(), "halves.nrrd", "/etc/passwd"); },
                 grpc::StatusCode::PERMISSION_DENIED, "table_path");
  ExpectRpcError([&] { client.LoadLabels("no-such-volume", "halves.nrrd"); }, grpc::StatusCode::NOT_FOUND,
                 "no-such-volume");
}

TEST_F(LabelsOverTheApi, BadSegmentationsAndStylesWithoutOneAreRefusedByName) {
  Client client = server_->Connect();
  const v1::VolumeInfo block = client.UploadVolume(scratch_ / "block.nrrd");
  std::ofstream(scratch_ / "bad.tsv") << "1\tleft\nright 2\n";
  ExpectRpcError([&] { client.UploadLabels(block.id(), scratch_ / "halves.nrrd", scratch_ / "bad.tsv"); },
                 grpc::StatusCode::INVALID_ARGUMENT, "header.label_table line 2");
  WriteNrrd(scratch_ / "far.nrrd", [](int, int, int) { return 1; });
  {
    std::ofstream out(scratch_ / "far.nhdr");  // the same voxels, a metre away
    out << "NRRD0004\ntype: unsigned short\ndimension: 3\nsizes: 32 32 32\nspace: left-posterior-superior\n"
           "space directions: (1,0,0) (0,1,0) (0,0,1)\nspace origin: (1000,0,0)\nencoding: raw\nendian: little\n"
           "byte skip: -1\ndata file: far.nrrd\n";
  }
  ExpectRpcError([&] { client.LoadLabels(block.id(), "far.nhdr"); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "does not overlap");
  v1::CreateSessionRequest request = SmallSession("ct-bone");
  request.set_volume_id(block.id());
  request.clear_preset();
  request.mutable_scene()->mutable_labels()->set_show_unlisted(false);
  ExpectRpcError([&] { client.CreateSession(request); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "has no segmentation");
}

// Issue 32: the table found when a CT loads, removed by one switch in the
// scene or a labels event, on a volume without a segmentation.
TEST(TableOverTheApi, AnUploadedCtSaysItHasATableAndOneSwitchRemovesIt) {
  ScratchDir scratch;
  const PatientOnTable patient;
  {
    std::ofstream out(scratch / "patient.nrrd", std::ios::binary);
    out << fmt::format("NRRD0004\ntype: short\ndimension: 3\nsizes: {} {} {}\nspacings: {} {} {}\n"
                       "encoding: raw\nendian: little\n\n",
                       patient.dims.x, patient.dims.y, patient.dims.z, patient.spacing_mm, patient.spacing_mm,
                       patient.spacing_mm);
    for (int z = 0; z < patient.dims.z; ++z)
      for (int y = 0; y < patient.dims.y; ++y)
        for (int x = 0; x < patient.dims.x; ++x) {
          const auto v = static_cast<std::int16_t>(patient.Hu(x, y, z));
          out.write(reinterpret_cast<const char*>(&v), 2);
        }
  }
  ServerProcess server(scratch.path(), {});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const v1::VolumeInfo volume = client.UploadVolume(scratch / "patient.nrrd");
  EXPECT_GT(volume.table().voxels(), 0u) << volume.table().note();
  EXPECT_NE(volume.table().note().find("table: 1 component"), std::string::npos) << volume.table().note();
  EXPECT_FALSE(volume.has_labels()) << "no segmentation: the table is no label set";

  // From behind (the table at large y, posterior), by events: the table is
  // in the picture until removed. Finals of 64 spp: at 16, two refinements of
  // one view differed by about as much as half the table's change.
  v1::CreateSessionRequest request = SmallSession("ct-soft-tissue", 96, 64, 64);
  request.set_volume_id(volume.id());
  const v1::CreateSessionResponse created = client.CreateSession(request);
  auto stream = client.Attach(created.session_id());
  v1::SessionEvent behind;
  behind.mutable_camera()->set_view(v1::POSTERIOR);
  const auto shown = WaitFinal(*stream, stream->Send(behind));
  ASSERT_TRUE(shown) << stream->status().error_message();
  ASSERT_TRUE(stream->state().has_value());
  const v1::Camera behind_camera = stream->state()->scene().camera();  // the view as the server resolved it
  v1::SessionEvent remove;
  remove.mutable_labels()->set_remove_table(true);
  const auto removed = WaitFinal(*stream, stream->Send(remove));
  ASSERT_TRUE(removed) << stream->status().error_message();
  v1::SessionEvent show;
  show.mutable_labels()->set_remove_table(false);
  const auto shown_again = WaitFinal(*stream, stream->Send(show));
  ASSERT_TRUE(shown_again) << stream->status().error_message();
  const double change = MeanAbsDiff(Decode(*shown), Decode(*removed));
  EXPECT_GT(change, 2.0) << "the table goes";
  EXPECT_LT(MeanAbsDiff(Decode(*shown), Decode(*shown_again)), change / 2) << "and comes back";

  // The same switch in the scene a session starts from, seen with the same
  // camera (removing the table does not move it).
  v1::CreateSessionRequest removed_from_start = request;
  removed_from_start.clear_preset();
  *removed_from_start.mutable_scene() = created.scene();
  *removed_from_start.mutable_scene()->mutable_camera() = behind_camera;
  removed_from_start.mutable_scene()->mutable_labels()->set_remove_table(true);
  const v1::CreateSessionResponse second = client.CreateSession(removed_from_start);
  EXPECT_TRUE(second.scene().labels().remove_table());
  auto second_stream = client.Attach(second.session_id());
  const auto from_start = WaitFinal(*second_stream);
  ASSERT_TRUE(from_start) << second_stream->status().error_message();
  EXPECT_LT(MeanAbsDiff(Decode(*removed), Decode(*from_start)), change / 2);

  // Styles still need a segmentation: the session ends naming it.
  v1::SessionEvent style;
  style.mutable_labels()->add_styles()->set_value(1);
  stream->Send(style);
  EXPECT_FALSE(WaitFinal(*stream, 5));
  EXPECT_NE(stream->status().error_message().find("had no segmentation"), std::string::npos)
      << stream->status().error_message();
}

}  // namespace
}  // namespace cinevol::testing
