// `cinevol slice` as scripts run it (issue 36): a phantom scene's axial
// slice is its voxel grid, one pixel per voxel; an oblique slice of a ball is
// its analytic circle; a real CT with its segmentation at the CT's own
// 512x512; bad requests exit 2 with one line.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "encode/image_codecs.h"
#include "io/phantom.h"
#include "reading/slice.h"
#include "service/server_process.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

std::pair<int, std::string> Cinevol(const ScratchDir& scratch, const std::vector<std::string>& args) {
  return RunProgram(CliPath(), args, scratch / "cinevol.log", 120s);
}

bool Has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

fs::path WriteScene(const ScratchDir& scratch, const std::string& json) {
  const fs::path path = scratch / "scene.json";
  std::ofstream(path) << json;
  return path;
}

// A ball of radius 10 mm (1000 in 0) on a grid of 0.5 x 0.5 x 2 mm voxels, as NRRD.
fs::path WriteAnisotropicBall(const ScratchDir& scratch) {
  const fs::path path = scratch / "ball.nrrd";
  constexpr int kX = 60, kY = 60, kZ = 15;
  std::ofstream out(path, std::ios::binary);
  out << "NRRD0004\ntype: short\ndimension: 3\nsizes: " << kX << " " << kY << " " << kZ
      << "\nspacings: 0.5 0.5 2\nencoding: raw\nendian: little\n\n";
  for (int z = 0; z < kZ; ++z) {
    for (int y = 0; y < kY; ++y) {
      for (int x = 0; x < kX; ++x) {
        const double dx = (x + 0.5 - kX / 2.0) * 0.5, dy = (y + 0.5 - kY / 2.0) * 0.5, dz = (z + 0.5 - kZ / 2.0) * 2;
        const std::int16_t v = dx * dx + dy * dy + dz * dz <= 100 ? 1000 : 0;
        out.write(reinterpret_cast<const char*>(&v), 2);
      }
    }
  }
  return path;
}

// The bright pixels' extent across and down the image (its widest row and tallest column).
std::pair<int, int> BrightExtent(const ImageRgb8& image) {
  int widest = 0, tallest = 0;
  for (int y = 0; y < image.height; ++y) {
    int n = 0;
    for (int x = 0; x < image.width; ++x) n += image.bytes[3 * (std::size_t(y) * image.width + x)] > 127;
    widest = std::max(widest, n);
  }
  for (int x = 0; x < image.width; ++x) {
    int n = 0;
    for (int y = 0; y < image.height; ++y) n += image.bytes[3 * (std::size_t(y) * image.width + x)] > 127;
    tallest = std::max(tallest, n);
  }
  return {widest, tallest};
}

// Image viewers show every pixel square: a coronal slice of anisotropic
// voxels is resampled to square pixels (the ball is round), or with
// --native-pixels keeps one pixel a voxel (the ball 4x squashed), and the
// line says the pixel size either way. --volume needs no scene file.
TEST(SliceCommand, CoronalSlicesOfAnisotropicVoxelsHaveSquarePixels) {
  ScratchDir scratch;
  const fs::path ball = WriteAnisotropicBall(scratch), out = scratch / "coronal.png";
  auto [code, output] = Cinevol(scratch, {"slice", "--volume", ball.string(), "--axis", "coronal", "--window", "1",
                                          "--level", "500", "--out", out.string()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_TRUE(Has(output, "0.5x0.5 mm")) << output;
  auto [wide, tall] = BrightExtent(ReadPng(out));
  EXPECT_NEAR(wide, 40, 2) << "20 mm across at 0.5 mm a pixel";
  EXPECT_NEAR(tall, wide, 0.08 * wide) << "the ball is round";
  std::tie(code, output) = Cinevol(scratch, {"slice", "--volume", ball.string(), "--axis", "coronal", "--window", "1",
                                             "--level", "500", "--native-pixels", "--out", out.string()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_TRUE(Has(output, "0.5x2 mm")) << output;
  std::tie(wide, tall) = BrightExtent(ReadPng(out));
  EXPECT_NEAR(wide, 4 * tall, 0.25 * wide) << "one pixel a voxel: 2 mm rows";
}

TEST(SliceCommand, AnAxialSliceOfAPhantomIsItsVoxelGrid) {
  ScratchDir scratch;
  const fs::path scene =
      WriteScene(scratch, R"({"volume": {"phantom": {"kind": "CUBE", "size": 40, "spacing": 0.5, "radius": 5}},
                      "clipping": {"planes": [{"normal": {"x": 1}}]}})");
  const fs::path out = scratch / "axial.png";
  auto [code, output] = Cinevol(scratch, {"slice", "--scene", scene.string(), "--axis", "axial", "--position", "0.25",
                                          "--window", "1", "--level", "500.5", "--out", out.string()});
  ASSERT_EQ(code, 0) << output;
  const ImageRgb8 image = ReadPng(out);
  EXPECT_EQ(image.width, 40);
  EXPECT_EQ(image.height, 40);
  EXPECT_EQ(image.bytes[3 * (20 * 40 + 20)], 255) << "the cube (1000) at the centre";
  EXPECT_EQ(image.bytes[0], 0) << "the background (0) at the corner";
  EXPECT_TRUE(Has(output, "axial z=0.25 mm, 40x40 px, 0.5x0.5 mm, window 1 level 500.5")) << output;
  EXPECT_TRUE(Has(output, "left R right L top A bottom P")) << output;
  EXPECT_EQ(image.bytes[3 * (20 * 40 + 15)], 255) << "the scene's clip plane is ignored without --clip";

  std::tie(code, output) = Cinevol(scratch, {"slice", "--scene", scene.string(), "--position", "0.25", "--window", "1",
                                             "--level", "500.5", "--clip", "--out", out.string()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_EQ(ReadPng(out).bytes[3 * (20 * 40 + 15)], 0) << "--clip: the patient's right (x < 0) is cut away";
  EXPECT_EQ(ReadPng(out).bytes[3 * (20 * 40 + 20)], 255) << "--clip: the patient's left is kept";

  std::tie(code, output) = Cinevol(scratch, {"slice", "--scene", scene.string(), "--axis", "sagittal", "--slab", "4",
                                             "--projection", "mean", "--preset", "bone", "--out", out.string()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_TRUE(Has(output, "slab 4 mm mean")) << output;
  EXPECT_TRUE(Has(output, "left A right P top S bottom I")) << output;
}

TEST(SliceCommand, BadRequestsExitTwoWithOneLine) {
  ScratchDir scratch;
  const fs::path scene = WriteScene(scratch, R"({"volume": {"phantom": {"kind": "SPHERE", "size": 16}}})");
  const std::string out = (scratch / "s.png").string();
  auto [code, output] = Cinevol(scratch, {"slice", "--scene", scene.string(), "--position", "50", "--out", out});
  EXPECT_EQ(code, 2);
  EXPECT_TRUE(Has(output, "outside the volume's axial range [-7.500, 7.500] mm")) << output;
  std::tie(code, output) = Cinevol(scratch, {"slice", "--scene", scene.string(), "--window", "80", "--out", out});
  EXPECT_EQ(code, 2);
  EXPECT_TRUE(Has(output, "--window and --level go together")) << output;
  EXPECT_EQ(Cinevol(scratch, {"slice", "--scene", scene.string(), "--axis", "oblique", "--out", out}).first, 2);
  EXPECT_EQ(Cinevol(scratch, {"slice", "--scene", scene.string(), "--out", (scratch / "s.jpg").string()}).first, 2);
}

// A ball of radius 20 mm about LPS 0, cut by a plane 7 mm from its centre:
// `--axis oblique` shows the analytic circle of radius sqrt(20^2 - 7^2), every
// pixel more than a millimetre inside it white and outside it black, where
// the library's geometry for the same flags puts the pixels.
TEST(SliceCommand, AnObliqueSliceOfASphereIsItsAnalyticCircle) {
  ScratchDir scratch;
  v1::Phantom ball;
  ball.set_kind(v1::Phantom::SPHERE);
  ball.set_size(64);
  ball.set_radius(20);
  const fs::path scene =
      WriteScene(scratch, R"({"volume": {"phantom": {"kind": "SPHERE", "size": 64, "radius": 20}}})");
  const fs::path out = scratch / "oblique.png";
  auto [code, output] =
      Cinevol(scratch, {"slice", "--scene", scene.string(), "--axis", "oblique", "--point", "3,4,5", "--normal",
                        "1,2,2", "--row", "2,-1,0", "--window", "1", "--level", "500.5", "--out", out.string()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_TRUE(Has(output, "oblique through 3,4,5 mm, normal 0.3333,0.6667,0.6667, row 0.8944,-0.4472,0,")) << output;
  const ImageRgb8 image = ReadPng(out);

  SliceSpec spec;
  spec.axis = SliceAxis::kOblique;
  spec.point_lps = {3, 4, 5};
  spec.normal_lps = Normalize(Vec3f{1, 2, 2});
  spec.row_lps = Normalize(Vec3f{2, -1, 0});
  const SliceGeometry g = PlanSlice(MakePhantom(ball), spec);
  ASSERT_EQ(image.width, g.width);
  ASSERT_EQ(image.height, g.height);
  EXPECT_FLOAT_EQ(g.pixel_width_mm, 1) << "the volume's spacing";
  const float plane_offset = Dot(Vec3f{3, 4, 5}, g.normal);  // the centre's distance from the plane
  ASSERT_NEAR(plane_offset, 7, 1e-4f);
  const float circle_radius = std::sqrt(20.0f * 20.0f - plane_offset * plane_offset);
  int white = 0, wrong = 0;
  for (int row = 0; row < image.height; ++row) {
    for (int column = 0; column < image.width; ++column) {
      const int grey = image.bytes[3 * (std::size_t(row) * image.width + column)];
      white += grey == 255;
      const float from_centre = Length(g.PixelToPatient(float(column), float(row)));
      // Within a millimetre of the sphere, interpolation between voxels decides.
      if (from_centre <= 19) wrong += grey != 255;
      if (from_centre >= 21) wrong += grey != 0;
    }
  }
  EXPECT_EQ(wrong, 0) << "pixels off the analytic circle";
  EXPECT_NEAR(std::sqrt(white / float(M_PI)), circle_radius, 0.5f) << "the disc's area gives the circle's radius";
}

TEST(SliceCommand, BadObliqueFlagsExitTwoSayingWhy) {
  ScratchDir scratch;
  const fs::path scene = WriteScene(scratch, R"({"volume": {"phantom": {"kind": "SPHERE", "size": 16}}})");
  const std::string out = (scratch / "s.png").string();
  auto expect_refused = [&](std::vector<std::string> flags, const std::string& message) {
    std::vector<std::string> args{"slice", "--scene", scene.string(), "--out", out};
    args.insert(args.end(), flags.begin(), flags.end());
    const auto [code, output] = Cinevol(scratch, args);
    EXPECT_EQ(code, 2) << output;
    EXPECT_TRUE(Has(output, message)) << "expected '" << message << "' in: " << output;
    EXPECT_LE(std::count(output.begin(), output.end(), '\n'), 2) << output;
  };
  expect_refused({"--axis", "oblique"}, "--axis oblique needs --normal X,Y,Z");
  expect_refused({"--axis", "oblique", "--normal", "0,0,0"}, "--normal 0,0,0: a direction must not be zero");
  expect_refused({"--axis", "oblique", "--normal", "nan,0,1"}, "each number must be finite");
  expect_refused({"--axis", "oblique", "--normal", "0,inf,1"}, "each number must be finite");
  expect_refused({"--axis", "oblique", "--normal", "1,2"}, "--normal '1,2': give three numbers X,Y,Z");
  expect_refused({"--axis", "oblique", "--normal", "1,2,3,4"}, "give three numbers");
  expect_refused({"--axis", "oblique", "--normal", "0,0,1", "--point", "1;2;3"}, "--point '1;2;3'");
  expect_refused({"--axis", "oblique", "--normal", "0,0,1", "--row", "0,0,-2"},
                 "--row 0,0,-2 lies along --normal 0,0,1");
  expect_refused({"--axis", "oblique", "--normal", "0,0,1", "--position", "2"},
                 "--position is for axial, coronal and sagittal");
  expect_refused({"--axis", "oblique", "--normal", "0,0,1", "--point", "0,0,50"}, "misses the volume");
  expect_refused({"--axis", "coronal", "--normal", "0,1,0"}, "--point, --normal and --row are for --axis oblique");
  expect_refused({"--point", "0,0,0"}, "--point, --normal and --row are for --axis oblique");
}

// A real CT (512 x 512 x 20 DICOM, JPEG 2000) with its TotalSegmentator
// labels: an axial slice at the CT's own spacing, soft tissue, labels painted.
TEST(SliceCommand, ARealCtSliceKeepsItsGridAndPaintsItsLabels) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const fs::path data = SharedData() / "ct-body-totalsegmentator";
  ScratchDir scratch;
  const fs::path scene =
      WriteScene(scratch, R"({"volume": {"dicomFolder": ")" + (data / "example_ct_dicom").string() +
                              R"(", "labels": ")" + (data / "example_seg_dicom.nii.gz").string() +
                              R"(", "labelTable": ")" + (data / "labels-total.tsv").string() + R"("}})");
  const fs::path out = scratch / "ct.png";
  auto [code, output] =
      Cinevol(scratch, {"slice", "--scene", scene.string(), "--preset", "soft-tissue", "--out", out.string()});
  ASSERT_EQ(code, 0) << output;
  const ImageRgb8 image = ReadPng(out);
  EXPECT_EQ(image.width, 512);
  EXPECT_EQ(image.height, 512);
  EXPECT_TRUE(Has(output, "window 350 level 50 (soft-tissue)")) << output;
  EXPECT_TRUE(Has(output, "left R right L top A bottom P")) << output;
  int coloured = 0;
  for (std::size_t i = 0; i < image.bytes.size(); i += 3) coloured += image.bytes[i] != image.bytes[i + 1];
  EXPECT_GT(coloured, 1000) << "the segmentation's organs are painted";
  std::tie(code, output) = Cinevol(scratch, {"slice", "--scene", scene.string(), "--no-labels", "--out", out.string()});
  ASSERT_EQ(code, 0) << output;
  const ImageRgb8 grey = ReadPng(out);
  coloured = 0;
  for (std::size_t i = 0; i < grey.bytes.size(); i += 3) coloured += grey.bytes[i] != grey.bytes[i + 1];
  EXPECT_EQ(coloured, 0) << "--no-labels: grey only";
}

}  // namespace
}  // namespace cinevol::testing
