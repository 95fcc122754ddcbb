// The GPU's JPEG encoder (pipeline/cuda_jpeg_encoder.cu): the same bytes as
// the CPU's interval coder from the same planes, at every chroma mode, odd
// sizes, qualities and interval lengths; a frame too dense for its room is
// given back to the host's encoder; a frame larger than any before still
// joins whole; and a CUDA pipeline sends only the JPEG. Skipped without a GPU.
#include <gtest/gtest.h>

#include <vector>

#include "core/error.h"
#include "core/ycc.h"
#include "encode/image_codecs.h"
#include "encode/jpeg_intervals.h"
#include "image_metrics.h"
#include "pipeline/display.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/jpeg_encoder.h"
#include "support/gpu.h"
#include "support/small_scene.h"

namespace cinevol {
namespace {

using testing::SmallHead;
using testing::SmallScene;

// Smooth shading, an edge and noise of `amplitude` (1: every sample random).
ImageYcc8 Planes(int width, int height, ChromaSubsampling chroma, float amplitude = 0.05f) {
  ImageRgbF image{width, height, std::vector<Vec3f>(std::size_t(width) * height)};
  unsigned state = 11;
  auto noise = [&] {
    state = state * 1664525u + 1013904223u;
    return amplitude * float(state >> 8) / float(1u << 24);
  };
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const bool inside = (x - width / 2) * (x - width / 2) + (y - height / 3) * (y - height / 3) < width * height / 9;
      const Vec3f base = inside ? Vec3f{0.7f, 0.5f, 0.3f * y / height} : Vec3f{0.02f, 0.1f, 0.4f * x / width};
      image.pixels[std::size_t(y) * width + x] = base * (1.0f - amplitude) + Vec3f{noise(), noise(), noise()};
    }
  }
  DisplayInputs in;
  in.width = width;
  in.height = height;
  in.radiance = image.pixels.data();
  in.chroma = chroma;
  return MakeCpuDisplay()->Run(in);
}

#if CINEVOL_WITH_CUDA

TEST(CudaJpegEncoder, WritesTheCpuCodersBytes) {
  CINEVOL_REQUIRE_CUDA();
  for (ChromaSubsampling chroma : {ChromaSubsampling::k444, ChromaSubsampling::k422, ChromaSubsampling::k420}) {
    for (const auto& [w, h] : {std::pair{1280, 720}, std::pair{173, 131}, std::pair{37, 21}, std::pair{1, 1}}) {
      const ImageYcc8 planes = Planes(w, h, chroma);
      for (int quality : {50, 80, 95}) {
        for (int blocks : {6, 96, kMaxBlocksPerInterval}) {
          const CudaJpegSettings settings{.blocks_per_interval = blocks};
          const std::vector<std::uint8_t> gpu = EncodeOnGpu(planes, quality, settings);
          EXPECT_EQ(gpu, EncodeJpegInIntervals(planes, quality, settings.mcus_per_interval(chroma)))
              << "chroma " << int(chroma) << ", " << w << "x" << h << " q" << quality << ", " << blocks << " blocks";
        }
      }
    }
  }
}

TEST(CudaJpegEncoder, GivesBackAFrameTooDenseForItsRoom) {
  CINEVOL_REQUIRE_CUDA();
  const ImageYcc8 noise = Planes(64, 64, ChromaSubsampling::k444, 1.0f);
  EXPECT_TRUE(EncodeOnGpu(noise, 100, {.slot_bytes_per_block = 8}).empty()) << "the host encodes it instead";
  EXPECT_EQ(EncodeOnGpu(noise, 100, {}),
            EncodeJpegInIntervals(noise, 100, CudaJpegSettings{}.mcus_per_interval(ChromaSubsampling::k444)))
      << "the default room holds white noise at quality 100";
}

TEST(CudaJpegEncoder, FramesLargerThanAnyBeforeStillJoinWhole) {
  CINEVOL_REQUIRE_CUDA();
  const ImageYcc8 flat = Planes(640, 360, ChromaSubsampling::k420, 0.0f);
  const ImageYcc8 noisy = Planes(640, 360, ChromaSubsampling::k420, 1.0f);
  const std::vector<ImageYcc8> frames = {flat, noisy, flat, noisy};
  const std::vector<std::vector<std::uint8_t>> encoded = EncodeOnGpu(frames, 95, {});
  ASSERT_EQ(encoded.size(), frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const int mcus = CudaJpegSettings{}.mcus_per_interval(ChromaSubsampling::k420);
    EXPECT_EQ(encoded[i], EncodeJpegInIntervals(frames[i], 95, mcus)) << "frame " << i;
  }
  EXPECT_GT(encoded[1].size(), 8 * encoded[0].size()) << "the noisy frame outgrew the first guess";
}

TEST(CudaJpegEncoder, APipelineSendsOnlyTheJpeg) {
  CINEVOL_REQUIRE_CUDA();
  ASSERT_EQ(ChooseJpegEncoder(JpegEncoderKind::kAuto, Backend::kCuda), JpegEncoderKind::kCuda);
  auto volume = SmallHead();
  const v1::Scene scene = SmallScene(*volume, 161, 97, 4);
  FramePipeline on_host(Backend::kCuda, volume), on_gpu(Backend::kCuda, volume);
  on_gpu.SetJpegEncoder(JpegEncoderKind::kCuda);
  on_host.Update(scene, FrameSettings{});
  on_gpu.Update(scene, FrameSettings{});
  for (int frame = 0; frame < 3; ++frame) {
    const DisplayFrame planes = on_host.RenderFrame(), encoded = on_gpu.RenderFrame();
    ASSERT_TRUE(encoded.image.data == nullptr) << "only the JPEG leaves the GPU";
    ASSERT_FALSE(encoded.jpeg.bytes.empty());
    EXPECT_EQ(encoded.jpeg.width, 161);
    EXPECT_EQ(encoded.jpeg.height, 97);
    EXPECT_GT(encoded.encode_ms, 0.0);
    const ImageRgb8 from_gpu = DecodeJpeg(encoded.jpeg.bytes);
    const ImageRgb8 from_cpu = DecodeJpeg(EncodeJpeg(planes.image, planes.jpeg_quality));
    EXPECT_GT(Psnr(from_gpu, from_cpu), 35.0) << "frame " << frame << ": the same picture, rendered twice";
  }
}

#endif  // CINEVOL_WITH_CUDA

TEST(JpegEncoderChoice, TheGpusEncoderNeedsFramesRenderedOnAGpu) {
  EXPECT_EQ(ParseJpegEncoder("cuda"), JpegEncoderKind::kCuda);
  EXPECT_EQ(ChooseJpegEncoder(JpegEncoderKind::kAuto, Backend::kCpu), JpegEncoderKind::kCpu);
  EXPECT_THROW(ChooseJpegEncoder(JpegEncoderKind::kCuda, Backend::kCpu), InputError);
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  EXPECT_THROW(pipeline.SetJpegEncoder(JpegEncoderKind::kCuda), InputError);
}

}  // namespace
}  // namespace cinevol
