// nvJPEG, loaded at run time: a missing or wrong library is reported, "auto"
// needs none of it, a request for nvJPEG that cannot run is refused naming
// why, and on a GPU with nvJPEG a rendered frame's JPEG decodes like the CPU's.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/ycc.h"
#include "encode/image_codecs.h"
#include "encode/nvjpeg_library.h"
#include "image_metrics.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/jpeg_encoder.h"
#include "support/gpu.h"
#include "support/small_scene.h"

namespace cinevol {
namespace {

using testing::SmallHead;
using testing::SmallScene;

const NvjpegLookup kMissing{nullptr, "libnvjpeg not found: none of libnvjpeg.so.13 loads"};

bool Contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(NvjpegLibrary, AnAbsentLibraryIsReportedNotFound) {
  const NvjpegLookup found = FindNvjpeg({"/nonexistent/libnvjpeg.so.13", "libnvjpeg-absent.so.99"});
  EXPECT_EQ(found.library, nullptr);
  EXPECT_TRUE(Contains(found.why_not, "libnvjpeg not found")) << found.why_not;
  EXPECT_TRUE(Contains(found.why_not, "none of libnvjpeg.so.13, libnvjpeg-absent.so.99 loads")) << found.why_not;
  EXPECT_TRUE(Contains(found.why_not, "from /nonexistent, the loader's path")) << found.why_not;
}

TEST(NvjpegLibrary, ALibraryWithoutItsEntryPointsIsNotTakenForIt) {
  const NvjpegLookup found = FindNvjpeg({"libm.so.6"});
  EXPECT_EQ(found.library, nullptr);
  EXPECT_TRUE(Contains(found.why_not, "libm.so.6 lacks nvjpegCreateSimple")) << found.why_not;
}

TEST(NvjpegLibrary, IsLookedForUnderCudasFoldersToo) {
  const std::vector<std::string> candidates = NvjpegCandidates();
  ASSERT_FALSE(candidates.empty());
  EXPECT_EQ(candidates.front(), "libnvjpeg.so.13") << "the loader's path first, newest first";
  EXPECT_NE(std::find(candidates.begin(), candidates.end(), "/usr/local/cuda/lib64/libnvjpeg.so.13"),
            candidates.end());
  EXPECT_NE(std::find(candidates.begin(), candidates.end(),
                      "/usr/local/cuda/targets/x86_64-linux/lib/libnvjpeg.so.12"),
            candidates.end());
}

TEST(JpegEncoderChoice, ParsesTheFlag) {
  EXPECT_EQ(ParseJpegEncoder("auto"), JpegEncoderKind::kAuto);
  EXPECT_EQ(ParseJpegEncoder("cpu"), JpegEncoderKind::kCpu);
  EXPECT_EQ(ParseJpegEncoder("nvjpeg"), JpegEncoderKind::kNvjpeg);
  EXPECT_THROW(ParseJpegEncoder("gpu"), InputError);
}

TEST(JpegEncoderChoice, AutoTakesTheGpusOwnCoderWithoutNvjpeg) {
  EXPECT_EQ(ChooseJpegEncoder(JpegEncoderKind::kAuto, Backend::kCuda, kMissing), JpegEncoderKind::kCuda);
  EXPECT_EQ(ChooseJpegEncoder(JpegEncoderKind::kAuto, Backend::kCpu, kMissing), JpegEncoderKind::kCpu);
  EXPECT_EQ(ChooseJpegEncoder(JpegEncoderKind::kCpu, Backend::kCuda, kMissing), JpegEncoderKind::kCpu);
  // This machine's own search, whatever it finds, never throws; without a
  // GPU backend the CPU encodes.
  EXPECT_NO_THROW(ProcessNvjpeg());
  EXPECT_EQ(ChooseJpegEncoder(JpegEncoderKind::kAuto, Backend::kCpu), JpegEncoderKind::kCpu);
}

TEST(JpegEncoderChoice, NvjpegWithoutTheLibraryIsRefusedNamingIt) {
  try {
    ChooseJpegEncoder(JpegEncoderKind::kNvjpeg, Backend::kCuda, kMissing);
    ADD_FAILURE() << "nvjpeg chosen without the library";
  } catch (const InputError& e) {
    EXPECT_TRUE(Contains(e.what(), "--jpeg-encoder nvjpeg")) << e.what();
    EXPECT_TRUE(Contains(e.what(), "libnvjpeg not found")) << e.what();
  }
  EXPECT_THROW(ChooseJpegEncoder(JpegEncoderKind::kNvjpeg, Backend::kCpu), InputError)
      << "frames rendered on the CPU, whether or not the library is here";
}

TEST(JpegEncoderChoice, APipelineOnTheCpuRefusesNvjpegAndKeepsItsPlanes) {
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  EXPECT_THROW(pipeline.SetJpegEncoder(JpegEncoderKind::kNvjpeg), InputError);
  pipeline.SetJpegEncoder(JpegEncoderKind::kCpu);
  pipeline.Update(SmallScene(*volume), FrameSettings{});
  const DisplayFrame frame = pipeline.RenderFrame();
  EXPECT_GT(frame.image.size, 0u);
  EXPECT_TRUE(frame.jpeg.bytes.empty());
  EXPECT_EQ(frame.jpeg_quality, FrameSettings{}.jpeg_quality);
}

// The same frame rendered by two CUDA pipelines, one encoding on the host with
// libjpeg-turbo, one on the GPU with nvJPEG, at each chroma subsampling and an
// odd size: both JPEGs decode to the same picture within JPEG noise, at
// similar sizes.
TEST(NvjpegEncoder, CudaFrameDecodesLikeTheCpuOne) {
  CINEVOL_REQUIRE_CUDA();
  const NvjpegLookup& nvjpeg = ProcessNvjpeg();
  if (!nvjpeg.library) GTEST_SKIP() << "no nvJPEG: " << nvjpeg.why_not;
  ASSERT_EQ(ChooseJpegEncoder(JpegEncoderKind::kNvjpeg, Backend::kCuda), JpegEncoderKind::kNvjpeg);
  auto volume = SmallHead();
  const v1::Scene scene = SmallScene(*volume, 161, 97, 4);
  for (ChromaSubsampling chroma : {ChromaSubsampling::k420, ChromaSubsampling::k422, ChromaSubsampling::k444}) {
    FramePipeline on_host(Backend::kCuda, volume), on_gpu(Backend::kCuda, volume);
    on_gpu.SetJpegEncoder(JpegEncoderKind::kNvjpeg);
    FrameSettings settings;
    settings.chroma = chroma;
    on_host.Update(scene, settings);
    on_gpu.Update(scene, settings);
    const DisplayFrame planes = on_host.RenderFrame(), encoded = on_gpu.RenderFrame();
    ASSERT_GT(planes.image.size, 0u);
    ASSERT_TRUE(encoded.image.data == nullptr) << "only the JPEG leaves the GPU";
    ASSERT_FALSE(encoded.jpeg.bytes.empty());
    EXPECT_EQ(encoded.jpeg.width, 161);
    EXPECT_EQ(encoded.jpeg.height, 97);
    EXPECT_EQ(encoded.jpeg_quality, planes.jpeg_quality);

    const std::vector<std::uint8_t> cpu_jpeg = EncodeJpeg(planes.image, planes.jpeg_quality);
    const ImageRgb8 from_cpu = DecodeJpeg(cpu_jpeg), from_gpu = DecodeJpeg(encoded.jpeg.bytes);
    ASSERT_EQ(from_gpu.width, from_cpu.width);
    ASSERT_EQ(from_gpu.height, from_cpu.height);
    const double psnr = Psnr(from_gpu, from_cpu);
    EXPECT_GT(psnr, 35.0) << "chroma " << int(chroma);
    EXPECT_GT(Psnr(from_gpu, ToRgb(planes.image)), 30.0) << "chroma " << int(chroma) << ": against the displayed";
    const double ratio = double(encoded.jpeg.bytes.size()) / double(cpu_jpeg.size());
    EXPECT_GT(ratio, 0.5) << "chroma " << int(chroma);
    EXPECT_LT(ratio, 2.0) << "chroma " << int(chroma);
    std::printf("chroma %d: PSNR %.2f dB, nvJPEG %zu bytes, libjpeg-turbo %zu bytes\n", int(chroma), psnr,
                encoded.jpeg.bytes.size(), cpu_jpeg.size());
  }
}

}  // namespace
}  // namespace cinevol
