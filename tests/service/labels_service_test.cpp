// Segmentations through the API, over real gRPC to a real server: upload and
// load a label volume for a volume, read its names, style its labels by
// event; and the errors that name what is wrong (issue 22).
#include <gtest/gtest.h>

#include <fstream>

#include "core/image_metrics.h"
#include "server_process.h"
#include "service_test_support.h"
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
    server_ = std::make_unique<ServerProcess>(scratch_.path(), std::vector<std::string>{"--data-root", scratch_.path().string()});
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

}  // namespace
}  // namespace cinevol::testing
