// FramePipeline: edits reset exactly what they invalidate, frames without
// refinement are the denoiser's output, and the CUDA chain agrees with the
// CPU one (tests/pipeline/refine_test.cpp: refinement).
#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "io/phantom.h"
#include "scene/presets.h"
#include "scene/scene_builder.h"
#include "scene/scene_file.h"
#include "pipeline/frame_pipeline.h"
#include "support/gpu.h"
#include "support/small_scene.h"

namespace cinevol {
namespace {

using testing::SmallHead;
using testing::SmallScene;

std::vector<std::uint8_t> Bytes(const ImageYcc8& image) { return {image.data.get(), image.data.get() + image.size}; }

double MeanAbsDiff(const ImageYcc8& a, const ImageYcc8& b) {
  const std::vector<std::uint8_t> x = Bytes(a), y = Bytes(b);
  double sum = 0;
  for (std::size_t i = 0; i < x.size(); ++i) sum += std::abs(int(x[i]) - int(y[i]));
  return sum / double(x.size());
}

// ... and rebuild only what the edit invalidates: a camera move resolves no
// transfer function and builds no majorants, a transfer-function edit one of
// each.
TEST(FramePipeline, EditsResetTheAccumulationOnlyWhenTheImageChanges) {
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  v1::Scene scene = SmallScene(*volume);
  FrameSettings settings;
  pipeline.Update(scene, settings);
  EXPECT_EQ(pipeline.transfer_function_builds(), 1u);
  const std::uint64_t majorants = pipeline.majorant_builds();
  EXPECT_GE(majorants, 1u);
  pipeline.RenderFrame();
  pipeline.RenderFrame();
  EXPECT_EQ(pipeline.accumulated_spp(), 4);

  settings.jpeg_quality = 20;  // encoding only
  pipeline.Update(scene, settings, 0);
  pipeline.RenderFrame();
  EXPECT_EQ(pipeline.accumulated_spp(), 6);

  scene.mutable_camera()->set_view(v1::LEFT);
  pipeline.Update(scene, settings, kCameraChanged);
  EXPECT_EQ(pipeline.accumulated_spp(), 0) << "a camera move";
  const std::uint64_t version = pipeline.scene_version();
  pipeline.RenderFrame();
  EXPECT_EQ(pipeline.scene_version(), version) << "a camera move rebuilt the transfer function or lights";
  EXPECT_EQ(pipeline.transfer_function_builds(), 1u) << "a camera move";
  EXPECT_EQ(pipeline.majorant_builds(), majorants) << "a camera move";

  scene.mutable_transfer_function()->set_preset("ct-soft-tissue");
  pipeline.Update(scene, settings, kTransferFunctionChanged);
  EXPECT_EQ(pipeline.accumulated_spp(), 0) << "a transfer-function edit";
  EXPECT_GT(pipeline.scene_version(), version);
  EXPECT_EQ(pipeline.transfer_function_builds(), 2u);
  EXPECT_EQ(pipeline.majorant_builds(), majorants + 1);
  pipeline.RenderFrame();

  scene.mutable_lights()->RemoveLast();
  pipeline.Update(scene, settings, kLightsChanged);
  EXPECT_EQ(pipeline.accumulated_spp(), 0) << "a light edit";
  EXPECT_EQ(pipeline.majorant_builds(), majorants + 1) << "a light edit";
  pipeline.RenderFrame();

  settings.denoiser.method = DenoiseMethod::kSvgf;  // a new denoiser, the same samples
  pipeline.Update(scene, settings, 0);
  EXPECT_EQ(pipeline.accumulated_spp(), 2);
  settings.denoiser.svgf.sigma_depth = 2;  // a knob of it: the same
  pipeline.Update(scene, settings, 0);
  EXPECT_EQ(pipeline.accumulated_spp(), 2);
  EXPECT_EQ(pipeline.transfer_function_builds(), 2u) << "settings edits";
}

// The benches drive the pipeline with scenes they resolved themselves; with
// refinement off every frame is the denoiser's output alone.
TEST(FramePipeline, ResolvedScenesAndFramesWithoutRefinement) {
  auto volume = SmallHead();
  const v1::Scene scene = SmallScene(*volume);
  FramePipeline from_proto(Backend::kCpu, volume), resolved(Backend::kCpu, volume);
  FrameSettings settings;
  settings.refine = false;
  settings.target_spp = 4;
  settings.denoiser.method = DenoiseMethod::kNone;
  settings.hold_codes = false;  // each frame's codes its own, as a fresh display's
  from_proto.Update(scene, settings);
  resolved.Update(ResolveScene(scene, *volume), settings);
  for (int i = 0; i < 3; ++i) {
    const DisplayFrame a = from_proto.RenderFrame(), b = resolved.RenderFrame();
    EXPECT_EQ(Bytes(a.image), Bytes(b.image)) << "frame " << i;
    // The display pass over the denoised image alone.
    const ImageRgbF denoised = resolved.DenoisedRadiance();
    DisplayInputs in;
    in.width = denoised.width;
    in.height = denoised.height;
    in.radiance = denoised.pixels.data();
    in.exposure = resolved.exposure();
    EXPECT_EQ(Bytes(b.image), Bytes(MakeCpuDisplay()->Run(in))) << "frame " << i << ": refinement is off";
  }
  EXPECT_TRUE(resolved.Converged());
}

// A still view through wRLS: once it has settled, most of what changes
// from frame to frame is 8-bit rounding of values that barely move. Held
// codes (FrameSettings::hold_codes) take half of it away here (0.54 of
// the plain change at 64x48).
TEST(FramePipeline, HeldCodesSteadyAStillView) {
  auto volume = SmallHead();
  const v1::Scene scene = SmallScene(*volume, 64, 48, 2);
  FrameSettings settings;
  settings.refine = false;  // the denoiser's output, frame after frame
  settings.chroma = ChromaSubsampling::k444;
  auto flicker = [&](bool hold) {
    settings.hold_codes = hold;
    FramePipeline pipeline(Backend::kCpu, volume);
    pipeline.Update(scene, settings);
    ImageYcc8 last;
    double change = 0;
    for (int frame = 0; frame < 16; ++frame) {
      ImageYcc8 shown = pipeline.RenderFrame().image;
      if (frame > 8) change += MeanAbsDiff(shown, last);
      last = std::move(shown);
    }
    return change;
  };
  const double plain = flicker(false), held = flicker(true);
  EXPECT_GT(plain, 0.0);
  EXPECT_LT(held, 0.7 * plain) << "plain " << plain << ", held " << held;
}

double MeanAbsLuminanceChange(const ImageRgbF& a, const ImageRgbF& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i) sum += std::abs(Luminance(a.pixels[i]) - Luminance(b.pixels[i]));
  return sum / double(a.pixels.size());
}

// wRLS recentres its output's history on each frame's estimate only where
// the shading may have changed. Told every frame that only the camera moved
// (as the study's still view is), the output of a view that holds still
// changes from frame to frame by less than told that the lights changed too,
// where the shift toward each frame's estimate is taken as a change of
// shading and passed on (0.84 of it at 48x32, 0.92 at 96x64).
TEST(FramePipeline, OnlyAMovedCameraKeepsTheOutputsHistory) {
  auto volume = SmallHead();
  const v1::Scene scene = SmallScene(*volume);
  FrameSettings settings;
  settings.refine = false;  // the denoiser's output, frame after frame
  auto change = [&](unsigned told) {
    FramePipeline pipeline(Backend::kCpu, volume);
    pipeline.Update(scene, settings);
    ImageRgbF last;
    double sum = 0;
    for (int frame = 0; frame < 16; ++frame) {
      if (frame > 0) pipeline.Update(scene, settings, told);
      pipeline.RenderFrame();
      ImageRgbF shown = pipeline.DenoisedRadiance();
      if (frame > 8) sum += MeanAbsLuminanceChange(shown, last);
      last = std::move(shown);
    }
    return sum;
  };
  const double moved = change(kCameraChanged), lit = change(kCameraChanged | kLightsChanged);
  EXPECT_GT(moved, 0.0);
  EXPECT_LT(moved, 0.9 * lit) << "only moved " << moved << ", lights changed " << lit;
}

// A denoiser that stops at surface normals asks the renderer for them
// (FrameRequest::surface_normals), and they change its output; its
// settings without the stop leave the frames as they were.
TEST(FramePipeline, ANormalStopGetsTheRenderersSurfaceNormals) {
  auto volume = SmallHead();
  const v1::Scene scene = SmallScene(*volume);
  auto denoised = [&](float normal_stop) {
    FrameSettings settings;
    settings.refine = false;
    settings.denoiser.wrls.atrous_normal_stop = normal_stop;
    FramePipeline pipeline(Backend::kCpu, volume);
    pipeline.Update(scene, settings);
    pipeline.RenderFrame();
    return pipeline.DenoisedRadiance();
  };
  const ImageRgbF plain = denoised(0.0f), stopped = denoised(16.0f);
  ASSERT_EQ(stopped.pixels.size(), plain.pixels.size());
  int differ = 0;
  for (std::size_t i = 0; i < plain.pixels.size(); ++i) {
    ASSERT_TRUE(IsFinite(stopped.pixels[i])) << "pixel " << i;
    differ += !(stopped.pixels[i] == plain.pixels[i]);
  }
  EXPECT_GT(differ, 0) << "the normals changed nothing";
  const ImageRgbF again = denoised(0.0f);
  for (std::size_t i = 0; i < plain.pixels.size(); ++i) ASSERT_TRUE(again.pixels[i] == plain.pixels[i]);
}

TEST(FramePipeline, ResizeChangesTheFrameSize) {
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  v1::Scene scene = SmallScene(*volume);
  pipeline.Update(scene, {});
  EXPECT_EQ(pipeline.RenderFrame().image.width, 48);
  scene.mutable_render()->set_width(20);
  scene.mutable_render()->set_height(10);
  pipeline.Update(scene, {});
  const DisplayFrame frame = pipeline.RenderFrame();
  EXPECT_EQ(frame.image.width, 20);
  EXPECT_EQ(frame.image.height, 10);
  EXPECT_EQ(frame.image.size, 20u * 10u + 2u * 10u * 5u) << "Y, then Cb and Cr at 4:2:0";
}

TEST(FramePipeline, CudaAgreesWithCpu) {
  CINEVOL_REQUIRE_CUDA();
  auto volume = SmallHead();
  FramePipeline cpu(Backend::kCpu, volume), gpu(Backend::kCuda, volume);
  EXPECT_EQ(gpu.backend(), Backend::kCuda);
  FrameSettings settings;
  settings.target_spp = 64;
  const v1::Scene scene = SmallScene(*volume, 64, 48);
  cpu.Update(scene, settings);
  gpu.Update(scene, settings);
  for (int i = 0; i < 32; ++i) {
    const DisplayFrame a = cpu.RenderFrame(), b = gpu.RenderFrame();
    ASSERT_EQ(a.image.size, b.image.size);
    // The same samples, denoiser and blend: only float rounding differs.
    EXPECT_LT(MeanAbsDiff(a.image, b.image), 1.5) << "frame " << i;
    EXPECT_EQ(a.final, b.final);
  }
}

// Sessions whose frames one thread makes share its frame scratch
// (device/frame_scratch.h): interleaved, at different sizes, still and
// moving, each makes the very frames it makes alone.
class FrameScratchShared : public ::testing::TestWithParam<Backend> {};

TEST_P(FrameScratchShared, InterleavedSessionsMakeTheFramesEachMakesAlone) {
  if (GetParam() == Backend::kCuda) CINEVOL_REQUIRE_CUDA();
  auto volume = SmallHead();
  constexpr int kFrames = 6;
  FrameSettings settings;
  settings.interactive_frame_ms = 0;  // full size while moving: no clock in the frames
  struct Session {
    v1::Scene scene;
    float step_mm;  // the camera's move before frames 2 and 4
    std::unique_ptr<FramePipeline> pipeline;
    void Start(Backend backend, const std::shared_ptr<const Volume>& volume, const FrameSettings& settings) {
      pipeline = std::make_unique<FramePipeline>(backend, volume);
      pipeline->Update(scene, settings);
    }
    std::vector<std::uint8_t> Frame(int i, const FrameSettings& settings) {
      if (i == 2 || i == 4) {
        v1::Vec3& eye = *scene.mutable_camera()->mutable_eye();
        eye.set_x(eye.x() + step_mm);
        pipeline->Update(scene, settings, kCameraChanged);
      }
      return Bytes(pipeline->RenderFrame().image);
    }
  };
  const auto start_small = [&] { return Session{SmallScene(*volume, 40, 24), 6.0f, nullptr}; };
  const auto start_large = [&] { return Session{SmallScene(*volume, 64, 48), -9.0f, nullptr}; };
  const auto alone = [&](Session session) {
    session.Start(GetParam(), volume, settings);
    std::vector<std::vector<std::uint8_t>> frames;
    for (int i = 0; i < kFrames; ++i) frames.push_back(session.Frame(i, settings));
    return frames;
  };
  const auto small_alone = alone(start_small()), large_alone = alone(start_large());
  Session small = start_small(), large = start_large();
  small.Start(GetParam(), volume, settings);
  large.Start(GetParam(), volume, settings);
  for (int i = 0; i < kFrames; ++i) {
    EXPECT_EQ(large.Frame(i, settings), large_alone[std::size_t(i)]) << "the larger session's frame " << i;
    EXPECT_EQ(small.Frame(i, settings), small_alone[std::size_t(i)]) << "the smaller session's frame " << i;
  }
}

// Sessions on threads of their own, at once: on a GPU their frames take
// and give back the pool's sets, each waiting on its stream for the set's
// last frame; each makes the very frames it makes alone.
TEST_P(FrameScratchShared, ConcurrentSessionsMakeTheFramesEachMakesAlone) {
  if (GetParam() == Backend::kCuda) CINEVOL_REQUIRE_CUDA();
  auto volume = SmallHead();
  constexpr int kSessions = 4, kFrames = 8;
  FrameSettings settings;
  settings.interactive_frame_ms = 0;
  const auto frames = [&](int session) {
    v1::Scene scene = SmallScene(*volume, 56 + 4 * session, 40);  // one size class: they share sets
    scene.mutable_camera()->mutable_eye()->set_y(scene.camera().eye().y() + 7.0f * session);
    FramePipeline pipeline(GetParam(), volume);
    pipeline.Update(scene, settings);
    std::vector<std::vector<std::uint8_t>> out;
    for (int i = 0; i < kFrames; ++i) out.push_back(Bytes(pipeline.RenderFrame().image));
    return out;
  };
  std::vector<std::vector<std::vector<std::uint8_t>>> alone, together(kSessions);
  for (int k = 0; k < kSessions; ++k) alone.push_back(frames(k));
  std::vector<std::thread> threads;
  for (int k = 0; k < kSessions; ++k) threads.emplace_back([&, k] { together[std::size_t(k)] = frames(k); });
  for (std::thread& t : threads) t.join();
  for (int k = 0; k < kSessions; ++k) EXPECT_EQ(together[std::size_t(k)], alone[std::size_t(k)]) << "session " << k;
}

// On a GPU a session's frames take their scratch from the GPU's pool, not
// from the thread that makes them: once the first frames at rest made the
// set (the refinement's planes from the second frame), frames on new threads
// take it, where sets of their own would take 200 MiB each at 720p.
TEST(FrameScratch, OnAGpuFramesOnOtherThreadsTakeTheSetThePoolHolds) {
  CINEVOL_REQUIRE_CUDA();
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCuda, volume);
  pipeline.Update(SmallScene(*volume, 1280, 720), FrameSettings{});
  const auto frames_on_a_new_thread = [&](int frames) {
    std::thread([&] {
      for (int i = 0; i < frames; ++i) pipeline.RenderFrame();
    }).join();
  };
  const auto free_mib = [] { return double(ListGpus().at(0).free_bytes) / (1 << 20); };
  frames_on_a_new_thread(kMinFramesForError);  // every buffer the session and its frames use
  const double after_first = free_mib();
  for (int i = 0; i < 3; ++i) frames_on_a_new_thread(1);
  EXPECT_NEAR(free_mib(), after_first, 8.0) << "frames on new threads made scratch of their own";
}

INSTANTIATE_TEST_SUITE_P(Backends, FrameScratchShared, ::testing::Values(Backend::kCpu, Backend::kCuda),
                         [](const ::testing::TestParamInfo<Backend>& info) { return std::string(ToString(info.param)); });

}  // namespace
}  // namespace cinevol
