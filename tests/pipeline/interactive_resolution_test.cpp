// Interactive resolution: while the view moves under a frame-time budget the
// pipeline renders fewer pixels and upsamples them to the viewport; once it
// holds still it refines at full size, and only a full-size frame is final.
// InteractiveResolution.* check the GPU's policy (steps through 0.75, 0.5, 0.375)
// on the CPU; CpuLiveView.* the CPU's own (sizes and samples from measured
// costs, preemptible still frames).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <iterator>
#include <cmath>
#include <thread>
#include <vector>

#include "core/ycc.h"
#include "encode/image_codecs.h"
#include "image_metrics.h"
#include "pipeline/frame_pipeline.h"
#include "support/gpu.h"
#include "support/small_scene.h"

namespace cinevol {
namespace {

using testing::SmallHead;
using testing::SmallScene;

// A camera move: the view zooms.
void Zoom(v1::Scene& scene, float degrees) {
  scene.mutable_camera()->set_fov_y_deg(scene.camera().fov_y_deg() - degrees);
}

struct Shown {
  float scale;
  int rendered_width;  // of the accumulation behind the frame
  int width, height;   // of the image
  bool final;
};

Shown Render(FramePipeline& pipeline) {
  const DisplayFrame f = pipeline.RenderFrame();
  return {f.resolution_scale, pipeline.AccumulatedRadiance().width, f.image.width, f.image.height, f.final};
}

FrameSettings WithBudget(float ms) {
  FrameSettings s;
  s.target_spp = 2;
  s.interactive_frame_ms = ms;
  return s;
}

// Moves the view frame by frame (at most 20 frames) until a frame renders at
// `until`; returns the scales seen. Every frame is checked for its size.
std::vector<float> Move(FramePipeline& pipeline, v1::Scene& scene, const FrameSettings& settings,
                        unsigned change, float until) {
  std::vector<float> scales;
  for (int step = 0; step < 20 && (scales.empty() || scales.back() != until); ++step) {
    if (change == kCameraChanged) {
      Zoom(scene, 0.5f);
    } else {
      scene.mutable_transfer_function()->set_density_scale(scene.transfer_function().density_scale() * 0.9f);
    }
    pipeline.Update(scene, settings, change);
    const Shown moving = Render(pipeline);
    scales.push_back(moving.scale);
    EXPECT_EQ(moving.width, 64) << "upsampled to the viewport, at scale " << moving.scale;
    EXPECT_EQ(moving.height, 40);
    EXPECT_EQ(moving.rendered_width, int(std::lround(64 * moving.scale)));
    if (moving.scale < 1.0f) {
      EXPECT_FALSE(moving.final) << "a small frame never ends refinement";
    }
  }
  return scales;
}

constexpr float kSmallestGpuScale = kInteractiveScales[std::size(kInteractiveScales) - 1];

TEST(InteractiveResolution, AMovingViewStepsDownAndRefinesAtFullSize) {
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  pipeline.SetInteractivePolicy(InteractivePolicy::kSteps);
  v1::Scene scene = SmallScene(*volume, 64, 40, 1);
  const FrameSettings settings = WithBudget(1e-3f);  // no frame meets it
  pipeline.Update(scene, settings);
  EXPECT_EQ(Render(pipeline).scale, 1.0f) << "nothing moved";

  const std::vector<float> scales = Move(pipeline, scene, settings, kCameraChanged, kSmallestGpuScale);
  ASSERT_EQ(scales.back(), kSmallestGpuScale) << "the scale steps down to the smallest";
  EXPECT_EQ(std::count(scales.begin(), scales.end(), 1.0f), kFrameTimesPerStep)
      << "a step waits for that many frame times";
  EXPECT_GT(std::count(scales.begin(), scales.end(), 0.75f), 0) << "through 0.75";
  EXPECT_GT(std::count(scales.begin(), scales.end(), 0.5f), 0) << "through 0.5";

  std::this_thread::sleep_for(std::chrono::milliseconds(kInteractionHoldMs + 50));
  Shown still = Render(pipeline);
  EXPECT_EQ(still.scale, 1.0f) << "the view held still: full size again";
  EXPECT_EQ(still.rendered_width, 64);
  if (!still.final) still = Render(pipeline);
  EXPECT_TRUE(still.final);
  EXPECT_EQ(pipeline.accumulated_spp(), 2) << "the accumulation restarted at full size";

  Zoom(scene, 0.5f);
  pipeline.Update(scene, settings, kCameraChanged);
  EXPECT_EQ(Render(pipeline).scale, kSmallestGpuScale) << "the next interaction starts where the last one ended";
}

TEST(InteractiveResolution, AFrameWithinTheBudgetStaysFullSize) {
  auto volume = SmallHead();
  for (const float budget : {0.0f, 1e6f}) {
    FramePipeline pipeline(Backend::kCpu, volume);
    pipeline.SetInteractivePolicy(InteractivePolicy::kSteps);
    v1::Scene scene = SmallScene(*volume, 64, 40, 1);
    pipeline.Update(scene, WithBudget(budget));
    Render(pipeline);
    const std::vector<float> scales = Move(pipeline, scene, WithBudget(budget), kCameraChanged, 0.0f);
    EXPECT_EQ(std::count(scales.begin(), scales.end(), 1.0f), 20) << "budget " << budget;
  }
}

TEST(InteractiveResolution, AMovingTransferFunctionAlsoScales) {
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  pipeline.SetInteractivePolicy(InteractivePolicy::kSteps);
  v1::Scene scene = SmallScene(*volume, 64, 40, 1);
  pipeline.Update(scene, WithBudget(1e-3f));
  Render(pipeline);
  EXPECT_EQ(Move(pipeline, scene, WithBudget(1e-3f), kTransferFunctionChanged, kSmallestGpuScale).back(),
            kSmallestGpuScale);
}

constexpr float kSmallestCpuScale = kCpuInteractiveScales[std::size(kCpuInteractiveScales) - 1];

TEST(CpuLiveView, AMovingViewTakesTheSizeThatFitsFromItsFirstFrame) {
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  v1::Scene scene = SmallScene(*volume, 64, 40, 2);
  const FrameSettings settings = WithBudget(1e-3f);  // no frame meets it
  pipeline.Update(scene, settings);
  const DisplayFrame still = pipeline.RenderFrame();
  EXPECT_EQ(still.resolution_scale, 1.0f) << "nothing moved";
  EXPECT_EQ(still.spp, 2);

  Zoom(scene, 0.5f);
  pipeline.Update(scene, settings, kCameraChanged);
  const DisplayFrame moving = pipeline.RenderFrame();
  EXPECT_EQ(moving.resolution_scale, kSmallestCpuScale) << "no stepping through the sizes between";
  EXPECT_EQ(moving.spp, 1);
  EXPECT_EQ(moving.image.width, 64) << "upsampled to the viewport";
  EXPECT_EQ(pipeline.AccumulatedRadiance().width, 8);

  std::this_thread::sleep_for(std::chrono::milliseconds(kInteractionHoldMs + 50));
  const DisplayFrame refined = pipeline.RenderFrame();
  EXPECT_EQ(refined.resolution_scale, 1.0f) << "the view held still: full size again";
  EXPECT_EQ(pipeline.AccumulatedRadiance().width, 64);
}

TEST(CpuLiveView, AFrameWithinTheBudgetKeepsTheFullSizeAndTheScenesSamples) {
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  v1::Scene scene = SmallScene(*volume, 64, 40, 2);
  pipeline.Update(scene, WithBudget(1e6f));
  pipeline.RenderFrame();
  for (int i = 0; i < 5; ++i) {
    Zoom(scene, 0.5f);
    pipeline.Update(scene, WithBudget(1e6f), kCameraChanged);
    const DisplayFrame f = pipeline.RenderFrame();
    EXPECT_EQ(f.resolution_scale, 1.0f);
    EXPECT_EQ(f.spp, 2);
  }
}

TEST(CpuLiveView, AMovedLightIsAnInteraction) {
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  v1::Scene scene = SmallScene(*volume, 64, 40, 2);
  pipeline.Update(scene, WithBudget(1e-3f));
  pipeline.RenderFrame();
  pipeline.Update(scene, WithBudget(1e-3f), kLightsChanged);
  EXPECT_LT(pipeline.RenderFrame().resolution_scale, 1.0f) << "on a CPU a full-size frame per light step takes seconds";
}

TEST(CpuLiveView, StillFramesNeverPassTheRefinementCap) {
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  FrameSettings settings = WithBudget(70);
  settings.target_spp = 7;
  settings.error_target = 0;
  pipeline.Update(SmallScene(*volume, 64, 40, 2), settings);
  int frames = 0;
  for (; frames < 10; ++frames) {
    const DisplayFrame f = pipeline.RenderFrame();
    EXPECT_EQ(f.resolution_scale, 1.0f);
    EXPECT_GE(f.spp, 1);
    if (f.final) break;
  }
  EXPECT_EQ(pipeline.accumulated_spp(), 7) << "the last frame takes what is left";
}

TEST(CpuLiveView, APreemptedStillFrameShowsNothingAndRestartsTheAccumulation) {
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  std::atomic<bool> preempt{false};
  pipeline.SetPreempt(&preempt);
  FrameSettings settings = WithBudget(70);
  settings.target_spp = 64;
  v1::Scene scene = SmallScene(*volume, 64, 40, 2);
  pipeline.Update(scene, settings);
  pipeline.RenderFrame();
  EXPECT_EQ(pipeline.accumulated_spp(), 2);

  preempt = true;  // an event arrived while the frame rendered
  const DisplayFrame stopped = pipeline.RenderFrame();
  EXPECT_TRUE(stopped.preempted);
  EXPECT_EQ(stopped.image.width, 0);
  EXPECT_EQ(pipeline.accumulated_spp(), 0);

  preempt = false;
  const DisplayFrame next = pipeline.RenderFrame();
  EXPECT_FALSE(next.preempted);
  EXPECT_EQ(next.image.width, 64);
  EXPECT_EQ(pipeline.accumulated_spp(), 2);

  // Moving frames are what the events are waiting for: never preempted.
  preempt = true;
  Zoom(scene, 0.5f);
  pipeline.Update(scene, settings, kCameraChanged);
  EXPECT_FALSE(pipeline.RenderFrame().preempted);
}

TEST(CpuLiveView, WithoutABudgetNothingChanges) {
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCpu, volume);
  std::atomic<bool> preempt{true};
  pipeline.SetPreempt(&preempt);
  v1::Scene scene = SmallScene(*volume, 64, 40, 2);
  pipeline.Update(scene, WithBudget(0));
  for (int i = 0; i < 3; ++i) {
    const DisplayFrame f = pipeline.RenderFrame();
    EXPECT_FALSE(f.preempted);
    EXPECT_EQ(f.spp, 2);
    EXPECT_EQ(f.resolution_scale, 1.0f);
    Zoom(scene, 0.5f);
    pipeline.Update(scene, WithBudget(0), kCameraChanged);
  }
}

// `image` stretched to width x height as a client does: bilinear between
// pixel centres, on the displayed 8-bit values.
ImageRgb8 Stretched(const ImageRgb8& image, int width, int height) {
  std::vector<Vec3f> source(std::size_t(image.width) * image.height);
  for (std::size_t i = 0; i < source.size(); ++i) {
    source[i] = {float(image.bytes[3 * i]), float(image.bytes[3 * i + 1]), float(image.bytes[3 * i + 2])};
  }
  const Vec3f* out = MakeCpuUpsampler()->Run(source.data(), image.width, image.height, width, height);
  ImageRgb8 stretched{width, height, std::vector<std::uint8_t>(std::size_t(width) * height * 3)};
  for (int i = 0; i < width * height; ++i) {
    for (int c = 0; c < 3; ++c) stretched.bytes[3 * i + c] = std::uint8_t(std::lround((&out[i].x)[c]));
  }
  return stretched;
}

// FrameSettings::frames_at_rendered_size: a smaller frame leaves at its own
// size, saying the viewport's; stretched by the client it shows what the
// server's upsampling would have.
TEST(InteractiveResolution, AFrameAtItsRenderedSizeIsWhatTheServerWouldHaveUpsampled) {
  auto volume = SmallHead();
  DisplayFrame frames[2];
  for (const bool at_rendered_size : {false, true}) {
    FramePipeline pipeline(Backend::kCpu, volume);
    // The GPU's steps: the scene's spp at every size (the CPU's cost model
    // picks samples from measured times), so both see the same samples.
    pipeline.SetInteractivePolicy(InteractivePolicy::kSteps);
    v1::Scene scene = SmallScene(*volume, 64, 40, 1);  // 1 spp: no frame ends refinement (target 2)
    FrameSettings settings = WithBudget(1e-3f);  // no frame meets it: down through 0.5
    settings.frames_at_rendered_size = at_rendered_size;
    pipeline.Update(scene, settings);
    pipeline.RenderFrame();
    for (int step = 0; step < 20 && frames[at_rendered_size].resolution_scale != 0.5f; ++step) {
      Zoom(scene, 0.5f);
      pipeline.Update(scene, settings, kCameraChanged);
      frames[at_rendered_size] = pipeline.RenderFrame();
    }
  }
  const DisplayFrame& upsampled = frames[0];
  const DisplayFrame& small = frames[1];
  ASSERT_EQ(small.resolution_scale, 0.5f);
  ASSERT_EQ(upsampled.resolution_scale, 0.5f);
  EXPECT_EQ(small.image.width, 32) << "the rendered size";
  EXPECT_EQ(small.image.height, 20);
  EXPECT_EQ(small.width, 64) << "shown at the viewport";
  EXPECT_EQ(small.height, 40);
  EXPECT_EQ(upsampled.image.width, 64);
  EXPECT_EQ(upsampled.width, 64);
  // Tone mapped before the stretch instead of after, and 4:2:0 chroma of
  // 32x20 pixels instead of 64x40: close, not equal.
  EXPECT_GT(Psnr(Stretched(ToRgb(small.image), 64, 40), ToRgb(upsampled.image)), 30.0);
}

// The GPU's frame at its rendered size, through the GPU's JPEG coder.
TEST(InteractiveResolution, CudaEncodesAFrameAtItsRenderedSize) {
  CINEVOL_REQUIRE_CUDA();
  auto volume = SmallHead();
  FramePipeline pipeline(Backend::kCuda, volume);
  pipeline.SetInteractivePolicy(InteractivePolicy::kCostModel);  // the smallest size from the first moving frame
  pipeline.SetJpegEncoder(JpegEncoderKind::kCuda);
  v1::Scene scene = SmallScene(*volume, 64, 40, 2);
  FrameSettings settings = WithBudget(1e-3f);
  settings.frames_at_rendered_size = true;
  pipeline.Update(scene, settings);
  pipeline.RenderFrame();
  Zoom(scene, 0.5f);
  pipeline.Update(scene, settings, kCameraChanged);
  const DisplayFrame moving = pipeline.RenderFrame();
  ASSERT_EQ(moving.resolution_scale, kSmallestCpuScale);
  ASSERT_FALSE(moving.jpeg.bytes.empty());
  const ImageRgb8 decoded = DecodeJpeg(moving.jpeg.bytes);
  EXPECT_EQ(decoded.width, 8);
  EXPECT_EQ(decoded.height, 5);
  EXPECT_EQ(moving.width, 64);
  EXPECT_EQ(moving.height, 40);
}

TEST(UpsamplePass, InterpolatesBetweenPixelCentresAndClampsAtEdges) {
  const std::vector<Vec3f> source = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};  // 2x2
  auto upsampler = MakeCpuUpsampler();
  const Vec3f* out = upsampler->Run(source.data(), 2, 2, 4, 4);
  // Target pixel centres map to source positions -0.25, 0.25, 0.75, 1.25.
  EXPECT_FLOAT_EQ(out[0].x, 0.0f) << "clamped to the corner";
  EXPECT_FLOAT_EQ(out[1].x, 0.25f);
  EXPECT_FLOAT_EQ(out[2].x, 0.75f);
  EXPECT_FLOAT_EQ(out[3].x, 1.0f);
  EXPECT_FLOAT_EQ(out[4 * 3 + 3].x, 3.0f);
  EXPECT_FLOAT_EQ(out[4 * 1 + 1].x, 0.75f) << "(0.25, 0.25): 0.25 on the top row, 2.25 on the bottom";
}

}  // namespace
}  // namespace cinevol
