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

#include <zlib.h>

#include "core/error.h"
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

// A frame's pixels come from a server: a header claiming a huge image is
// refused before anything that size is allocated.
TEST(Decoders, RefuseImagesBeyondTheLargestViewport) {
  std::vector<std::uint8_t> jpeg = EncodeJpeg(ImageRgb8{8, 8, std::vector<std::uint8_t>(8 * 8 * 3, 128)}, 80);
  const std::uint8_t sof0[] = {0xFF, 0xC0};
  const auto sof = std::search(jpeg.begin(), jpeg.end(), std::begin(sof0), std::end(sof0));
  ASSERT_NE(sof, jpeg.end());
  sof[5] = sof[6] = sof[7] = sof[8] = 0xEA;  // 60138 x 60138
  try {
    DecodeJpeg(jpeg);
    ADD_FAILURE() << "a 60138x60138 JPEG was decoded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("beyond 8192x8192"), std::string::npos) << e.what();
  }

  std::vector<std::uint8_t> png = EncodePng(ImageRgb8{1, 1, {1, 2, 3}});
  ASSERT_EQ(std::string(png.begin() + 12, png.begin() + 16), "IHDR");
  png[16] = png[17] = 0;  // width 0x0000FFFF, the CRC made to match
  png[18] = png[19] = 0xFF;
  const std::uint32_t crc = std::uint32_t(crc32(0, png.data() + 12, 17));
  for (int i = 0; i < 4; ++i) png[29 + i] = std::uint8_t(crc >> (24 - 8 * i));
  try {
    DecodePng(png);
    ADD_FAILURE() << "a 65535-pixel-wide PNG was decoded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("beyond 8192x8192"), std::string::npos) << e.what();
  }
}

// The lossless final frame: the tone-mapped pixels themselves.
TEST(Display, RgbIsTheToneMappedPixels) {
  const ImageRgbF radiance = Frame(13, 7);
  DisplayInputs in;
  in.width = radiance.width;
  in.height = radiance.height;
  in.radiance = radiance.pixels.data();
  in.exposure = 0.5f;
  const ImageRgb8 rgb = MakeCpuDisplay()->RunRgb(in);
  ASSERT_EQ(rgb.bytes.size(), std::size_t(13 * 7 * 3));
  for (int i = 0; i < 13 * 7; ++i) {
    std::uint8_t expected[3];
    ToneMapPixel(radiance.pixels[i], exp2f(0.5f), expected);
    for (int c = 0; c < 3; ++c) ASSERT_EQ(rgb.bytes[3 * i + c], expected[c]) << "pixel " << i;
  }
}

}  // namespace
}  // namespace cinevol
