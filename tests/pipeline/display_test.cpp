// The display pass's YCbCr planes: libjpeg-turbo's own conversion and
// downsampling of the same sRGB image within a code value (every chroma mode,
// odd sizes), the CUDA display within a code value of the CPU one (GPU
// machine; skips elsewhere), and frames that keep their planes while later
// frames render.
#include <gtest/gtest.h>
#include <turbojpeg.h>

#include <bit>
#include <cmath>
#include <limits>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "core/tone_map.h"
#include "core/ycc.h"
#include "io/phantom.h"
#include "pipeline/display.h"
#include "pipeline/tone_map_table.h"
#include "pipeline/upsample.h"
#include "render/renderer.h"
#include "support/gpu.h"

namespace cinevol {
namespace {

// Smooth ramps with per-pixel noise, so that neighbouring pixels differ and
// the chroma averages round both ways.
ImageRgbF TestRadiance(int width, int height) {
  ImageRgbF image{width, height, std::vector<Vec3f>(std::size_t(width) * height)};
  unsigned state = 12345;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      Vec3f c{2.0f * x / width, 1.5f * y / height, 0.3f + 0.2f * std::sin(0.7f * float(x + y))};
      for (int i = 0; i < 3; ++i) {
        state = state * 1664525u + 1013904223u;
        c[i] += 0.25f * float(state >> 8) / float(1u << 24);
      }
      image.pixels[std::size_t(y) * width + x] = c;
    }
  }
  return image;
}

DisplayInputs InputsFor(const Vec3f* radiance, int width, int height, ChromaSubsampling chroma) {
  DisplayInputs in;
  in.width = width;
  in.height = height;
  in.radiance = radiance;
  in.exposure = 0.5f;
  in.chroma = chroma;
  return in;
}

int TjSubsampling(ChromaSubsampling chroma) {
  switch (chroma) {
    case ChromaSubsampling::k444: return TJSAMP_444;
    case ChromaSubsampling::k422: return TJSAMP_422;
    case ChromaSubsampling::k420: return TJSAMP_420;
  }
  return TJSAMP_420;
}

// The largest difference between two images' planes, over `a`'s plane sizes.
int MaxPlaneDifference(const ImageYcc8& a, const std::uint8_t* const b_planes[3], const int b_strides[3]) {
  int worst = 0;
  for (int c = 0; c < 3; ++c) {
    for (int y = 0; y < a.PlaneHeight(c); ++y) {
      for (int x = 0; x < a.PlaneWidth(c); ++x) {
        const int d = std::abs(int(a.Plane(c)[std::size_t(y) * a.PlaneWidth(c) + x]) -
                               int(b_planes[c][std::size_t(y) * b_strides[c] + x]));
        worst = std::max(worst, d);
      }
    }
  }
  return worst;
}

struct Case {
  ChromaSubsampling chroma;
  int width, height;
};

void PrintTo(const Case& c, std::ostream* os) {
  const char* names[] = {"444", "422", "420"};
  *os << names[int(c.chroma)] << "_" << c.width << "x" << c.height;
}

class DisplayPlanes : public ::testing::TestWithParam<Case> {};

TEST_P(DisplayPlanes, MatchLibjpegTurbosConversionOfTheSameImage) {
  const Case c = GetParam();
  const ImageRgbF radiance = TestRadiance(c.width, c.height);
  const DisplayInputs in = InputsFor(radiance.pixels.data(), c.width, c.height, c.chroma);
  const ImageYcc8 planes = MakeCpuDisplay()->Run(in);
  ASSERT_EQ(planes.width, c.width);
  ASSERT_EQ(planes.height, c.height);
  ASSERT_EQ(planes.size, YccBytes(c.width, c.height, c.chroma));

  // The same sRGB image through TurboJPEG's colour conversion and downsampling.
  const ImageRgb8 rgb = ToneMap(radiance, in.exposure);
  const int subsampling = TjSubsampling(c.chroma);
  std::vector<std::uint8_t> reference[3];
  std::uint8_t* reference_planes[3];
  int strides[3];
  for (int p = 0; p < 3; ++p) {
    strides[p] = tjPlaneWidth(p, c.width, subsampling);
    reference[p].resize(tjPlaneSizeYUV(p, c.width, strides[p], c.height, subsampling));
    reference_planes[p] = reference[p].data();
  }
  tjhandle tj = tjInitCompress();
  ASSERT_NE(tj, nullptr);
  const int status = tjEncodeYUVPlanes(tj, rgb.bytes.data(), c.width, 0, c.height, TJPF_RGB, reference_planes,
                                       strides, subsampling, 0);
  const std::string error = status == 0 ? "" : tjGetErrorStr2(tj);
  tjDestroy(tj);
  ASSERT_EQ(status, 0) << error;
  const std::uint8_t* const expected[3] = {reference_planes[0], reference_planes[1], reference_planes[2]};
  EXPECT_LE(MaxPlaneDifference(planes, expected, strides), 1);
}

INSTANTIATE_TEST_SUITE_P(ChromaAndSizes, DisplayPlanes,
                         ::testing::Values(Case{ChromaSubsampling::k444, 33, 17}, Case{ChromaSubsampling::k422, 33, 17},
                                           Case{ChromaSubsampling::k420, 33, 17}, Case{ChromaSubsampling::k420, 64, 48},
                                           Case{ChromaSubsampling::k420, 1, 1}, Case{ChromaSubsampling::k422, 5, 2},
                                           Case{ChromaSubsampling::k420, 2, 7}));

TEST(DisplayPlanes, AFrameKeepsItsPlanesWhileLaterFramesRender) {
  const ImageRgbF bright = TestRadiance(20, 10);
  ImageRgbF dark = bright;
  for (Vec3f& v : dark.pixels) v = v * 0.1f;
  const auto display = MakeCpuDisplay();
  const ImageYcc8 held = display->Run(InputsFor(bright.pixels.data(), 20, 10, ChromaSubsampling::k420));
  const std::vector<std::uint8_t> held_bytes(held.data.get(), held.data.get() + held.size);
  for (int i = 0; i < 5; ++i) display->Run(InputsFor(dark.pixels.data(), 20, 10, ChromaSubsampling::k420));
  EXPECT_EQ(std::vector<std::uint8_t>(held.data.get(), held.data.get() + held.size), held_bytes);

  // Released frames' buffers come back: no allocation per frame.
  const std::uint8_t* first = display->Run(InputsFor(dark.pixels.data(), 20, 10, ChromaSubsampling::k420)).data.get();
  EXPECT_EQ(display->Run(InputsFor(dark.pixels.data(), 20, 10, ChromaSubsampling::k420)).data.get(), first);
}

// The CPU's table gives the formula's codes: around every step (where a
// wobble of the float curve would show) and across the range.
TEST(ToneMapTable, GivesTheFormulasCodesBitForBit) {
  const ToneMapTable& table = ToneMapTable::Get();
  auto expect_same = [&](float v) {
    std::uint8_t formula[3], looked_up[3];
    ToneMapPixel(Vec3f{v, v, v}, 1.0f, formula);
    table.Map(Vec3f{v, v, v}, 1.0f, looked_up);
    ASSERT_EQ(int(looked_up[0]), int(formula[0])) << "at " << v;
  };
  for (int code = 1; code < 256; ++code) {
    const std::uint32_t bits = std::bit_cast<std::uint32_t>(table.step(code));
    for (std::uint32_t b = bits - 256; b <= bits + 256; ++b) expect_same(std::bit_cast<float>(b));
  }
  for (float v = -1.0f; v < 40.0f; v = v < 1e-4f ? v + 1e-6f : v * 1.0001f) expect_same(v);
  for (const float v : {0.0f, -0.0f, 1e-38f, 1e30f, std::numeric_limits<float>::max()}) expect_same(v);
}

TEST(ToneMapTable, BlacksOutNonFinitePixelsAndScalesByTheExposure) {
  const ToneMapTable& table = ToneMapTable::Get();
  for (const Vec3f c : {Vec3f{std::numeric_limits<float>::quiet_NaN(), 1, 1},
                        Vec3f{1, std::numeric_limits<float>::infinity(), 1}, Vec3f{0.2f, 0.5f, 3.0f}}) {
    for (const float scale : {0.25f, 1.0f, 5.7f}) {
      std::uint8_t formula[3], looked_up[3];
      ToneMapPixel(c, scale, formula);
      table.Map(c, scale, looked_up);
      for (int i = 0; i < 3; ++i) EXPECT_EQ(int(looked_up[i]), int(formula[i]));
    }
  }
}

// The table's values before rounding (for held codes) are the formula's
// within a tenth of a code (the curve bends most within the wide steps
// near saturation).
TEST(ToneMapTable, GivesTheFormulasPositionsWithinATenthOfACode) {
  const ToneMapTable& table = ToneMapTable::Get();
  for (float v = -1.0f; v < 40.0f; v = v < 1e-4f ? v + 1e-6f : v * 1.0003f) {
    std::uint8_t codes[3];
    float formula[3], looked_up[3];
    ToneMapPixel(Vec3f{v, v, v}, 1.0f, codes, formula);
    table.Map(Vec3f{v, v, v}, 1.0f, codes, looked_up);
    ASSERT_NEAR(looked_up[0], formula[0], 0.1f) << "at " << v;
    ASSERT_NEAR(looked_up[0], float(codes[0]), 0.5f) << "at " << v;
  }
}

// The scaled radiance whose DisplayPosition is `position`, by bisection.
float ValueAtPosition(float position) {
  float lo = 0.0f, hi = 100.0f;
  for (int i = 0; i < 100; ++i) (DisplayPosition(0.5f * (lo + hi)) < position ? lo : hi) = 0.5f * (lo + hi);
  return hi;
}

// The grey every pixel of a frame of `value` shows, through `display`.
int ShownGrey(Display& display, float value, bool hold, int width = 8, int height = 4) {
  const std::vector<Vec3f> radiance(std::size_t(width) * height, Vec3f{value, value, value});
  DisplayInputs in = InputsFor(radiance.data(), width, height, ChromaSubsampling::k444);
  in.exposure = 0;
  in.hold_codes = hold;
  const ImageRgb8 shown = ToRgb(display.Run(in));
  for (std::uint8_t code : shown.bytes) EXPECT_EQ(code, shown.bytes[0]);
  return shown.bytes[0];
}

// A value that straddles a rounding step flips plain codes every frame; a
// held code stays until the value is a whole code from it. A frame of
// another size, or one that asks for exact codes, rounds plainly. (Grey:
// the luma is the grey's code, the chroma 128.)
TEST(DisplayPlanes, ACodeHoldsWhileItsValueStaysWithinACode) {
  const float below = ValueAtPosition(100.3f), above = ValueAtPosition(100.7f);
  const auto plain = MakeCpuDisplay();
  for (int frame = 0; frame < 4; ++frame) {
    EXPECT_EQ(ShownGrey(*plain, below, false), 100);
    EXPECT_EQ(ShownGrey(*plain, above, false), 101);
  }
  const auto held = MakeCpuDisplay();
  EXPECT_EQ(ShownGrey(*held, above, true), 101);  // the first frame has nothing to hold
  for (int frame = 0; frame < 4; ++frame) {
    EXPECT_EQ(ShownGrey(*held, below, true), 101);
    EXPECT_EQ(ShownGrey(*held, above, true), 101);
  }
  EXPECT_EQ(ShownGrey(*held, ValueAtPosition(100.1f), true), 101);
  EXPECT_EQ(ShownGrey(*held, ValueAtPosition(99.9f), true), 100);  // a whole code away
  EXPECT_EQ(ShownGrey(*held, ValueAtPosition(100.8f), true), 100);
  EXPECT_EQ(ShownGrey(*held, above, false), 101);                    // exact codes, also kept
  EXPECT_EQ(ShownGrey(*held, below, true), 101);
  EXPECT_EQ(ShownGrey(*held, below, true, 9, 4), 100);               // another size: nothing held
  EXPECT_EQ(ShownGrey(*held, ValueAtPosition(140.2f), true, 9, 4), 140);
}

// A moving CPU frame is upsampled inside the display: the same planes as the
// upsampler's image through the display.
TEST(DisplayPass, UpsamplingOnTheWayGivesTheUpsampledImagesPlanes) {
  const ImageRgbF small = TestRadiance(37, 21);
  const auto upsampler = MakeCpuUpsampler();
  for (ChromaSubsampling chroma : {ChromaSubsampling::k444, ChromaSubsampling::k420}) {
    const Vec3f* big = upsampler->Run(small.pixels.data(), 37, 21, 150, 83);
    const ImageYcc8 a = MakeCpuDisplay()->Run(InputsFor(big, 150, 83, chroma));
    const ImageYcc8 b =
        MakeCpuDisplay()->RunUpsampled(InputsFor(nullptr, 150, 83, chroma), small.pixels.data(), 37, 21);
    ASSERT_EQ(a.size, b.size);
    EXPECT_EQ(std::vector<std::uint8_t>(a.data.get(), a.data.get() + a.size),
              std::vector<std::uint8_t>(b.data.get(), b.data.get() + b.size));
  }
}

#if CINEVOL_WITH_CUDA
TEST(DisplayPlanes, CudaMatchesCpu) {
  CINEVOL_REQUIRE_CUDA();
  v1::Phantom p;
  p.set_kind(v1::Phantom::HEAD);
  p.set_size(32);
  p.set_spacing(6.0f);
  TransferFunction tf;
  tf.points = {{-100, 0, {0.9f, 0.6f, 0.5f}, {}, 0.5f, {}}, {300, 1, {0.9f, 0.9f, 0.8f}, {0.2f, 0.2f, 0.2f}, 0.4f, {}}};
  tf.density_scale = 0.3f;
  LightSetup lights;
  lights.environment.kind = Environment::Kind::kUniform;
  lights.environment.zenith = {0.8f, 0.8f, 0.8f};
  auto renderer = CreateRenderer(Backend::kCuda);
  renderer->SetVolume(std::make_shared<const Volume>(MakePhantom(p)));
  renderer->SetTransferFunction(tf);
  renderer->SetLights(lights);
  const int w = 63, h = 47;  // odd: edge blocks repeat edge pixels
  FrameRequest req;
  req.camera = LookAt({300, -300, 50}, {0, 0, 0}, {0, 0, 1}, 32, w, h);
  req.spp = 2;
  renderer->Render(req);
  const Vec3f* device = renderer->Targets().radiance;
  const ImageRgbF host = renderer->Radiance();
  const auto gpu = MakeCudaDisplay(), cpu = MakeCpuDisplay();
  for (ChromaSubsampling chroma : {ChromaSubsampling::k444, ChromaSubsampling::k422, ChromaSubsampling::k420}) {
    const ImageYcc8 a = gpu->Run(InputsFor(device, w, h, chroma));
    const ImageYcc8 b = cpu->Run(InputsFor(host.pixels.data(), w, h, chroma));
    ASSERT_EQ(a.size, b.size);
    const std::uint8_t* const b_planes[3] = {b.Plane(0), b.Plane(1), b.Plane(2)};
    const int strides[3] = {b.PlaneWidth(0), b.PlaneWidth(1), b.PlaneWidth(2)};
    // Only the GPU's float rounding (powf, fused multiply-adds) differs.
    EXPECT_LE(MaxPlaneDifference(a, b_planes, strides), 1) << "chroma " << int(chroma);
  }
  // The next frame holds the codes each display showed: the same on both
  // (the codes of the frames before may differ by one, so a fresh pair).
  const auto gpu_held = MakeCudaDisplay(), cpu_held = MakeCpuDisplay();
  for (int frame = 0; frame < 2; ++frame) {
    req.frame = std::uint32_t(frame + 1);  // new noise: some codes hold, some move
    renderer->Render(req);
    DisplayInputs gin = InputsFor(renderer->Targets().radiance, w, h, ChromaSubsampling::k444);
    const ImageRgbF next = renderer->Radiance();
    DisplayInputs cin = InputsFor(next.pixels.data(), w, h, ChromaSubsampling::k444);
    gin.hold_codes = cin.hold_codes = true;
    const ImageYcc8 a = gpu_held->Run(gin), b = cpu_held->Run(cin);
    const std::uint8_t* const b_planes[3] = {b.Plane(0), b.Plane(1), b.Plane(2)};
    const int strides[3] = {b.PlaneWidth(0), b.PlaneWidth(1), b.PlaneWidth(2)};
    EXPECT_LE(MaxPlaneDifference(a, b_planes, strides), 1) << "frame " << frame;
  }
}
#endif

}  // namespace
}  // namespace cinevol
