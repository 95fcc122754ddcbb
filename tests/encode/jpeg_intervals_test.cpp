// JPEG coded in restart intervals by encode/jpeg_blocks.h (the GPU encoder's
// source, run here on the CPU): its quantisation is libjpeg's rounding
// division, and its frames decode to exactly the pixels of libjpeg-turbo's
// encode of the same planes, at every chroma mode, odd sizes, qualities and
// interval lengths, at about the same size.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "core/tone_map.h"
#include "core/ycc.h"
#include "encode/image_codecs.h"
#include "encode/jpeg_intervals.h"
#include "encode/jpeg_tables.h"
#include "pipeline/display.h"

namespace cinevol {
namespace {

// A smooth picture with an edge, gradients and fine noise, as a rendered
// frame: every coefficient category and long zero runs occur.
ImageRgbF Frame(int width, int height, float noise_amplitude = 0.05f) {
  ImageRgbF image{width, height, std::vector<Vec3f>(std::size_t(width) * height)};
  unsigned state = 7;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      state = state * 1664525u + 1013904223u;
      const float noise = noise_amplitude * float(state >> 8) / float(1u << 24);
      const bool inside = (x - width / 3) * (x - width / 3) + (y - height / 2) * (y - height / 2) < width * height / 9;
      image.pixels[std::size_t(y) * width + x] =
          inside ? Vec3f{0.8f + noise, 0.5f + noise, 0.3f * y / height} : Vec3f{0.02f + noise, 0.1f, 0.4f * x / width};
    }
  }
  return image;
}

ImageYcc8 Planes(const ImageRgbF& radiance, ChromaSubsampling chroma) {
  DisplayInputs in;
  in.width = radiance.width;
  in.height = radiance.height;
  in.radiance = radiance.pixels.data();
  in.chroma = chroma;
  return MakeCpuDisplay()->Run(in);
}

TEST(JpegQuantization, IsLibjpegsRoundingDivisionForEveryValue) {
  for (int q = 1; q <= 255; ++q) {
    const jpeg::QuantDivisor d = jpeg::MakeQuantDivisor(q);
    ASSERT_EQ(d.divisor, 8 * q);
    for (int v = -(1 << 15) + 1; v < (1 << 15); ++v) {
      const int magnitude = (std::abs(v) + 4 * q) / (8 * q);
      const int expected = v < 0 ? -magnitude : magnitude;
      ASSERT_EQ(jpeg::Quantize(v, d), expected) << "value " << v << ", quantiser " << q;
    }
  }
}

TEST(JpegTables, AreLibjpegsAtEachQuality) {
  const jpeg::QualityTables& q50 = jpeg::TablesFor(50);
  EXPECT_EQ(q50.coding.divisor[0][0].divisor, 8 * 16) << "the standard luma table's DC at quality 50";
  EXPECT_EQ(q50.coding.divisor[1][0].divisor, 8 * 17) << "the standard chroma table's DC";
  EXPECT_EQ(q50.coding.dc[0].length[0], 2) << "the standard luma DC code of category 0: 00";
  EXPECT_EQ(q50.coding.ac[0].code[0], 0xA) << "the standard luma EOB: 1010";
  EXPECT_EQ(q50.coding.ac[0].length[0], 4);
  EXPECT_EQ(&jpeg::TablesFor(0), &jpeg::TablesFor(1)) << "qualities clamp to [1, 100]";
  EXPECT_EQ(jpeg::TablesFor(100).coding.divisor[0][5].divisor, 8);
}

class JpegIntervals : public ::testing::TestWithParam<ChromaSubsampling> {};

TEST_P(JpegIntervals, DecodeToExactlyLibjpegsPixels) {
  for (const auto& [w, h] : {std::pair{96, 64}, std::pair{173, 131}, std::pair{37, 21}, std::pair{1, 1},
                             std::pair{8, 300}}) {
    const ImageYcc8 planes = Planes(Frame(w, h), GetParam());
    for (int quality : {30, 80, 95, 100}) {
      const ImageRgb8 expected = DecodeJpeg(EncodeJpeg(planes, quality));
      for (int mcus : {1, 3, 16, 65535}) {
        const ImageRgb8 decoded = DecodeJpeg(EncodeJpegInIntervals(planes, quality, mcus));
        ASSERT_EQ(decoded.width, w);
        ASSERT_EQ(decoded.height, h);
        EXPECT_EQ(decoded.bytes, expected.bytes) << w << "x" << h << " q" << quality << ", " << mcus << " MCUs";
      }
    }
  }
}

// Intervals of 96 blocks (the GPU coder's default: 16 MCUs at 4:2:0, 32 at 4:4:4).
TEST_P(JpegIntervals, CostAFewPercentOverOneScan) {
  const ImageYcc8 planes = Planes(Frame(1280, 720, 0.02f), GetParam());
  const int blocks_per_mcu = GetParam() == ChromaSubsampling::k420 ? 6 : (GetParam() == ChromaSubsampling::k422 ? 4 : 3);
  const double whole = double(EncodeJpeg(planes, 80).size());
  const double one_scan = double(EncodeJpegInIntervals(planes, 80, 65535).size());
  const double in_intervals = double(EncodeJpegInIntervals(planes, 80, 96 / blocks_per_mcu).size());
  EXPECT_NEAR(one_scan / whole, 1.0, 0.002) << "the same coefficients and codes as libjpeg's";
  EXPECT_LT(in_intervals / whole, 1.05) << "markers, padding and DC restarts of 96-block intervals";
  std::printf("1280x720: libjpeg %.0f bytes, one scan %.0f, 96-block intervals %.0f\n", whole, one_scan, in_intervals);
}

INSTANTIATE_TEST_SUITE_P(Chroma, JpegIntervals,
                         ::testing::Values(ChromaSubsampling::k444, ChromaSubsampling::k422, ChromaSubsampling::k420));

TEST(JpegIntervals, NoiseAtQuality100StaysWithinTheBlockBound) {
  ImageRgbF noise{64, 64, std::vector<Vec3f>(64 * 64)};
  unsigned state = 3;
  for (Vec3f& p : noise.pixels) {
    for (float* c : {&p.x, &p.y, &p.z}) {
      state = state * 1664525u + 1013904223u;
      *c = float(state >> 8) / float(1u << 24);
    }
  }
  const ImageYcc8 planes = Planes(noise, ChromaSubsampling::k444);
  const std::vector<std::uint8_t> jpeg = EncodeJpegInIntervals(planes, 100, 1);
  const std::size_t blocks = 3 * 64;
  EXPECT_LT(jpeg.size(), blocks * jpeg::kMaxBytesPerBlock);
  EXPECT_EQ(DecodeJpeg(jpeg).bytes, DecodeJpeg(EncodeJpeg(planes, 100)).bytes);
}

}  // namespace
}  // namespace cinevol
