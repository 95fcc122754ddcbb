// JPEG from the display's YCbCr planes (libjpeg's raw-data path) decodes to
// the image that EncodeJpeg makes from the same frame's sRGB, for every chroma
// mode and odd sizes; planes that do not match their size are refused; ToRgb
// gives the pixels back.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "core/tone_map.h"
#include "core/ycc.h"
#include "encode/image_codecs.h"
#include "pipeline/display.h"

namespace cinevol {
namespace {

// A smooth scene with an edge and fine noise: what a rendered frame holds.
ImageRgbF Frame(int width, int height) {
  ImageRgbF image{width, height, std::vector<Vec3f>(std::size_t(width) * height)};
  unsigned state = 99;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      state = state * 1664525u + 1013904223u;
      const float noise = 0.05f * float(state >> 8) / float(1u << 24);
      const bool inside = (x - width / 2) * (x - width / 2) + (y - height / 2) * (y - height / 2) < width * height / 8;
      image.pixels[std::size_t(y) * width + x] =
          inside ? Vec3f{0.9f + noise, 0.6f, 0.4f * y / height} : Vec3f{0.05f, 0.1f + noise, 0.2f * x / width};
    }
  }
  return image;
}

ImageYcc8 Display(const ImageRgbF& radiance, ChromaSubsampling chroma) {
  DisplayInputs in;
  in.width = radiance.width;
  in.height = radiance.height;
  in.radiance = radiance.pixels.data();
  in.chroma = chroma;
  return MakeCpuDisplay()->Run(in);
}

struct Difference {
  double mean = 0;
  int max = 0;
};

Difference Compare(const ImageRgb8& a, const ImageRgb8& b) {
  Difference d;
  for (std::size_t i = 0; i < a.bytes.size(); ++i) {
    const int e = std::abs(int(a.bytes[i]) - int(b.bytes[i]));
    d.mean += e;
    d.max = std::max(d.max, e);
  }
  d.mean /= double(a.bytes.size());
  return d;
}

class JpegFromPlanes : public ::testing::TestWithParam<ChromaSubsampling> {};

TEST_P(JpegFromPlanes, DecodesLikeTheJpegOfTheSameSrgb) {
  for (const auto& [w, h] : {std::pair{96, 64}, std::pair{37, 21}, std::pair{1, 1}}) {
    const ImageRgbF frame = Frame(w, h);
    const ImageYcc8 planes = Display(frame, GetParam());
    const ImageRgb8 rgb = ToneMap(frame, 0.0f);
    for (int quality : {80, 95}) {
      const ImageRgb8 from_planes = DecodeJpeg(EncodeJpeg(planes, quality));
      const ImageRgb8 from_rgb = DecodeJpeg(EncodeJpeg(rgb, quality, GetParam()));
      ASSERT_EQ(from_planes.width, w);
      ASSERT_EQ(from_planes.height, h);
      const Difference d = Compare(from_planes, from_rgb);
      // Identical where no block is padded; at odd sizes libjpeg pads chroma
      // before downsampling, this encoder after, and the padding's DCT leaks
      // a little into the edge pixels.
      EXPECT_LT(d.mean, 1.0) << w << "x" << h << " q" << quality;
      EXPECT_LE(d.max, 6) << w << "x" << h << " q" << quality;
    }
  }
}

TEST_P(JpegFromPlanes, ToRgbGivesThePixelsBack) {
  const ImageRgbF frame = Frame(37, 21);
  const ImageRgb8 back = ToRgb(Display(frame, GetParam())), rgb = ToneMap(frame, 0.0f);
  ASSERT_EQ(back.bytes.size(), rgb.bytes.size());
  const Difference d = Compare(back, rgb);
  if (GetParam() == ChromaSubsampling::k444) {
    EXPECT_LE(d.max, 2) << "YCbCr rounding only";
  } else {
    EXPECT_LT(d.mean, 6.0) << "chroma shared by neighbours, across the disc's edge too";
  }
}

// Bands encoded on their own threads and joined by restart markers decode to
// exactly the pixels of one encode, at every size and band count (more bands
// than MCU rows included), and the joined stream does carry the restarts.
TEST_P(JpegFromPlanes, BandsEncodedInParallelDecodeToTheSamePixels) {
  for (const auto& [w, h] : {std::pair{96, 64}, std::pair{173, 131}, std::pair{37, 21}, std::pair{1, 1}}) {
    const ImageYcc8 planes = Display(Frame(w, h), GetParam());
    const std::vector<std::uint8_t> whole = EncodeJpeg(planes, 85);
    const ImageRgb8 expected = DecodeJpeg(whole);
    for (int bands : {2, 3, 4, 7, 1000}) {
      const std::vector<std::uint8_t> joined = EncodeJpeg(planes, 85, bands);
      const ImageRgb8 decoded = DecodeJpeg(joined);
      ASSERT_EQ(decoded.width, w);
      ASSERT_EQ(decoded.height, h);
      EXPECT_EQ(decoded.bytes, expected.bytes) << w << "x" << h << ", " << bands << " bands";
      const std::uint8_t restart_interval[] = {0xFF, 0xDD};
      const bool has_restarts = std::search(joined.begin(), joined.end(), std::begin(restart_interval),
                                            std::end(restart_interval)) != joined.end();
      EXPECT_EQ(has_restarts, h > 16) << w << "x" << h << ": one MCU row makes one band";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Chroma, JpegFromPlanes,
                         ::testing::Values(ChromaSubsampling::k444, ChromaSubsampling::k422, ChromaSubsampling::k420));

TEST(JpegFromPlanes, PlanesThatDoNotMatchTheirSizeAreRefused) {
  const ImageYcc8 good = Display(Frame(16, 16), ChromaSubsampling::k420);
  ImageYcc8 bad = good;
  bad.size = good.size - 1;
  EXPECT_THROW(EncodeJpeg(bad, 80), std::invalid_argument);
  bad = good;
  bad.width = 17;
  EXPECT_THROW(EncodeJpeg(bad, 80), std::invalid_argument);
  bad = good;
  bad.data.reset();
  EXPECT_THROW(EncodeJpeg(bad, 80), std::invalid_argument);
  EXPECT_THROW(EncodeJpeg(ImageYcc8{}, 80), std::invalid_argument);
  EXPECT_THROW(ToRgb(ImageYcc8{}), std::invalid_argument);
  EXPECT_NO_THROW(EncodeJpeg(good, 0)) << "quality clamps to [1, 100]";
}

}  // namespace
}  // namespace cinevol
