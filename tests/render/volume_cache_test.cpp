// Renderers of one volume on one device share one prepared copy (on a GPU one
// upload of the voxels), built once however many ask at once, freed with the
// last of them, and rendering exactly what a renderer alone renders.
#include <gtest/gtest.h>

#include <thread>
#include <vector>

#include "io/phantom.h"
#include "scene/presets.h"
#include "scene/scene_builder.h"
#include "scene/scene_file.h"
#include "pipeline/frame_pipeline.h"
#include "render/renderer.h"
#include "render_test_scenes.h"
#include "support/gpu.h"
#include "support/small_scene.h"

namespace cinevol {
namespace {

using testing::SmallHead;
using testing::UniformSky;

// A float volume: the prepared copy holds its quantised voxels.
std::shared_ptr<const Volume> FloatRamp() {
  std::vector<float> values(12 * 10 * 8);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = 0.25f * float(i % 97);
  VolumeMetadata meta;
  meta.source = "ramp";
  return std::make_shared<const Volume>(Vec3i{12, 10, 8}, Vec3f{1, 1, 1}, std::move(values), meta);
}

// The cache's copies of `volume`.
std::vector<VolumeCopyStatus> CopiesOf(const std::shared_ptr<const Volume>& volume) {
  std::vector<VolumeCopyStatus> copies;
  for (const VolumeCopyStatus& c : VolumeCache::Get().Copies()) {
    if (c.volume == volume.get()) copies.push_back(c);
  }
  return copies;
}

// Soft tissue to bone of the head phantom: bricks empty and dense.
TransferFunction HeadTransferFunction() {
  TransferFunction tf;
  tf.points = {{-200, 0, {0.9f, 0.6f, 0.5f}, {}, 0.5f, {}},
               {300, 0.8f, {0.9f, 0.9f, 0.8f}, {0.3f, 0.3f, 0.3f}, 0.3f, {}},
               {1500, 1, {0.9f, 0.9f, 0.8f}, {0.3f, 0.3f, 0.3f}, 0.3f, {}}};
  tf.density_scale = 0.3f;
  tf.gradient_factor = 1.5f;
  return tf;
}

ImageRgbF RenderFrames(Renderer& r, const std::shared_ptr<const Volume>& volume, int frames) {
  r.SetVolume(volume);
  r.SetTransferFunction(HeadTransferFunction());
  r.SetLights(UniformSky(1.0f));
  FrameRequest request;
  request.camera = LookAt({-300, -400, 150}, {0, 0, 0}, {0, 0, 1}, 30, 24, 16);
  request.spp = 2;
  request.seed = 7;
  for (int f = 0; f < frames; ++f) {
    request.frame = std::uint32_t(f);
    r.Render(request);
  }
  return r.AccumulatedMean();
}

double MeanOf(const ImageRgbF& image) {
  double sum = 0;
  for (const Vec3f& p : image.pixels) sum += p.x + p.y + p.z;
  return sum / double(image.pixels.size());
}

// Sessions of one volume that classify it alike (one preset) build and hold
// its majorants once; another transfer function gets its own, and the shared
// set goes with its last renderer.
TEST(VolumeCache, RenderersThatClassifyAlikeShareTheirMajorants) {
  const auto volume = SmallHead();
  const auto prepared = VolumeCache::Get().Acquire(volume, kDefaultBrickSize, kHostDevice);
  const std::size_t sets_before = VolumeCache::Get().MajorantSets();
  {
    SceneData a, b, c;
    for (SceneData* d : {&a, &b, &c}) d->SetVolume(prepared->prepared_ptr());
    a.SetTransferFunction(HeadTransferFunction());
    b.SetTransferFunction(HeadTransferFunction());
    TransferFunction denser = HeadTransferFunction();
    denser.density_scale *= 2;
    c.SetTransferFunction(denser);
    EXPECT_EQ(a.shared_majorants(), b.shared_majorants());
    EXPECT_NE(a.shared_majorants(), c.shared_majorants());
    EXPECT_EQ(VolumeCache::Get().MajorantSets(), sets_before + 2);
    b.SetReconstruction(Reconstruction::kTricubic);  // wider margins: other bricks' bounds
    EXPECT_NE(a.shared_majorants(), b.shared_majorants());
  }
  EXPECT_EQ(VolumeCache::Get().MajorantSets(), sets_before);
}

TEST(VolumeCache, TwoRenderersOnOneVolumeShareOneCopy) {
  const auto volume = FloatRamp();
  {
    auto a = CreateRenderer(Backend::kCpu), b = CreateRenderer(Backend::kCpu);
    a->SetVolume(volume);
    b->SetVolume(volume);
    const auto copies = CopiesOf(volume);
    ASSERT_EQ(copies.size(), 1u);
    EXPECT_EQ(copies[0].device, kHostDevice);
    EXPECT_EQ(copies[0].renderers, 2);
    // The quantised voxels (2 bytes each) and the brick ranges, once.
    EXPECT_GE(copies[0].bytes, volume->voxel_count() * 2);
  }
  EXPECT_TRUE(CopiesOf(volume).empty()) << "the last renderer frees the copy";
}

TEST(VolumeCache, TwoPipelinesOnOneVolumeShareOneCopy) {
  const auto volume = SmallHead();
  {
    FramePipeline a(Backend::kCpu, volume), b(Backend::kCpu, volume);
    const auto copies = CopiesOf(volume);
    ASSERT_EQ(copies.size(), 1u);
    EXPECT_EQ(copies[0].renderers, 2);
    EXPECT_EQ(DeviceLabel(copies[0].device), "cpu");
  }
  EXPECT_TRUE(CopiesOf(volume).empty());
}

TEST(VolumeCache, OtherBrickSizesAreOtherCopies) {
  const auto volume = SmallHead();
  RendererOptions unbricked;
  unbricked.brick_size = 0;
  auto a = CreateRenderer(Backend::kCpu), b = CreateRenderer(Backend::kCpu, unbricked);
  a->SetVolume(volume);
  b->SetVolume(volume);
  EXPECT_EQ(CopiesOf(volume).size(), 2u);
}

TEST(VolumeCache, RenderersAskingAtOnceGetOneCopy) {
  const auto volume = FloatRamp();
  constexpr int kThreads = 8;
  std::vector<std::unique_ptr<Renderer>> renderers(kThreads);
  std::vector<std::thread> threads;
  for (int i = 0; i < kThreads; ++i) {
    threads.emplace_back([&, i] {
      renderers[i] = CreateRenderer(Backend::kCpu);
      renderers[i]->SetVolume(volume);
    });
  }
  for (std::thread& t : threads) t.join();
  const auto copies = CopiesOf(volume);
  ASSERT_EQ(copies.size(), 1u);
  EXPECT_EQ(copies[0].renderers, kThreads);
  renderers.clear();
  EXPECT_TRUE(CopiesOf(volume).empty());
}

TEST(VolumeCache, ASharedCopyRendersWhatALoneRendererDoes) {
  const auto volume = SmallHead();
  auto alone = CreateRenderer(Backend::kCpu);
  const ImageRgbF lone = RenderFrames(*alone, volume, 3);
  alone.reset();
  auto a = CreateRenderer(Backend::kCpu), b = CreateRenderer(Backend::kCpu);
  const ImageRgbF first = RenderFrames(*a, volume, 3);
  const ImageRgbF second = RenderFrames(*b, volume, 3);
  EXPECT_EQ(first.pixels, lone.pixels);
  EXPECT_EQ(second.pixels, lone.pixels);
  EXPECT_GT(MeanOf(lone), 0.0) << "the head should show";
}

#if CINEVOL_WITH_CUDA
TEST(VolumeCache, CudaRenderersShareOneDeviceUpload) {
  CINEVOL_REQUIRE_CUDA();
  const auto volume = SmallHead();
  auto alone = CreateRenderer(Backend::kCuda);
  const ImageRgbF lone = RenderFrames(*alone, volume, 3);
  alone.reset();
  EXPECT_TRUE(CopiesOf(volume).empty());
  {
    auto a = CreateRenderer(Backend::kCuda), b = CreateRenderer(Backend::kCuda);
    const ImageRgbF first = RenderFrames(*a, volume, 3);
    const ImageRgbF second = RenderFrames(*b, volume, 3);
    const auto copies = CopiesOf(volume);
    ASSERT_EQ(copies.size(), 1u);
    EXPECT_GE(copies[0].device, 0);
    EXPECT_EQ(copies[0].renderers, 2);
    EXPECT_EQ(copies[0].bytes, volume->voxel_count() * 2) << "one upload of the 16-bit voxels, as a texture alone";
    EXPECT_EQ(first.pixels, lone.pixels);
    EXPECT_EQ(second.pixels, lone.pixels);
  }
  EXPECT_TRUE(CopiesOf(volume).empty()) << "the last renderer frees the upload";
  EXPECT_GT(MeanOf(lone), 0.0) << "the head should show";
}

// Without the texture (RendererOptions::volume_texture off) the voxels go up
// as a buffer: another copy, of the same 2 bytes a voxel, that renders the head.
TEST(VolumeCache, WithoutTheTextureTheDeviceHoldsABuffer) {
  CINEVOL_REQUIRE_CUDA();
  const auto volume = SmallHead();
  RendererOptions options;
  options.volume_texture = false;
  auto buffered = CreateRenderer(Backend::kCuda, options), textured = CreateRenderer(Backend::kCuda);
  const ImageRgbF a = RenderFrames(*buffered, volume, 3), b = RenderFrames(*textured, volume, 3);
  const auto copies = CopiesOf(volume);
  ASSERT_EQ(copies.size(), 2u) << "a buffer and a texture: two kinds of copy";
  for (const VolumeCopyStatus& c : copies) EXPECT_EQ(c.bytes, volume->voxel_count() * 2);
  EXPECT_GT(MeanOf(a), 0.0);
  EXPECT_NEAR(MeanOf(a), MeanOf(b), 0.05 * MeanOf(b)) << "the texture's interpolation differs only in its last bits";
}

// A segmentation is shared too: one copy per device (its labels per brick, and
// on a GPU one upload of the label voxels) for every renderer of it there,
// freed with the last; the renderer's own part is its label materials.
TEST(VolumeCache, RenderersOfOneSegmentationShareOneLabelCopy) {
  const auto volume = SmallHead();
  auto labels = std::make_shared<LabelVolume>();
  labels->dims = volume->dims();
  labels->labels.assign(volume->voxel_count(), 1);
  labels->voxels[1] = volume->voxel_count();
  const std::shared_ptr<const LabelVolume> shared = labels;
  std::vector<int> devices{kHostDevice};
  if (CudaAvailable()) devices.push_back(0);
  for (const int device : devices) {
    std::weak_ptr<const LabelCopy> seen;
    {
      const auto a = VolumeCache::Get().AcquireLabels(shared, {4, 4, 4}, device);
      const auto b = VolumeCache::Get().AcquireLabels(shared, {4, 4, 4}, device);
      EXPECT_EQ(a.get(), b.get()) << "device " << device;
      EXPECT_NE(a.get(), VolumeCache::Get().AcquireLabels(shared, {8, 8, 8}, device).get()) << "other bricks";
      EXPECT_EQ(a->brick_labels().offsets.size(), std::size_t(8 * 8 * 8) + 1) << "32^3 voxels in 4^3 bricks";
      seen = a;
    }
    EXPECT_TRUE(seen.expired()) << "the last holder frees the copy";
  }
}

// On a GPU too: one set of majorants on the host and one on the device for
// two renderers that classify alike, both gone with the renderers.
TEST(VolumeCache, CudaRenderersShareTheirMajorantsOnTheGpu) {
  CINEVOL_REQUIRE_CUDA();
  const auto volume = SmallHead();
  const std::size_t sets_before = VolumeCache::Get().MajorantSets();
  {
    auto a = CreateRenderer(Backend::kCuda), b = CreateRenderer(Backend::kCuda);
    RenderFrames(*a, volume, 1);
    RenderFrames(*b, volume, 1);
    EXPECT_EQ(VolumeCache::Get().MajorantSets(), sets_before + 2);
  }
  EXPECT_EQ(VolumeCache::Get().MajorantSets(), sets_before);
}

// What a resting 720p session's pipeline adds on the GPU beyond the shared voxels,
// and what that is made of: the renderer's frame buffers, the denoiser's and
// the rest of the pipeline (display, refinement), each measured by the GPU's
// free memory (2 MiB pages) around it. The first session's frame also makes
// the pool's frame scratch set (device/frame_scratch.h), which the later
// frames take in turn. Printed for docs/performance.md.
TEST(VolumeCache, PrintsTheDeviceMemoryOfA720pSession) {
  CINEVOL_REQUIRE_CUDA();
  const auto volume = SmallHead();
  v1::Scene scene = MakePresetScene("ct-bone", *volume);
  scene.mutable_render()->set_width(1280);
  scene.mutable_render()->set_height(720);
  ApplyDefaults(scene);
  const auto free_mib = [] { return double(ListGpus().at(0).free_bytes) / (1 << 20); };
  const double free_before = free_mib();
  // At rest long enough for the refinement's every buffer (kMinFramesForError frames).
  const auto rest = [&](FramePipeline& pipeline) {
    pipeline.Update(scene, FrameSettings{});
    for (int i = 0; i < kMinFramesForError; ++i) pipeline.RenderFrame();
  };
  FramePipeline first(Backend::kCuda, volume);
  rest(first);
  const double free_one = free_mib();
  FramePipeline second(Backend::kCuda, volume);
  rest(second);
  const double free_two = free_mib();
  const double voxels_mib = double(CopiesOf(volume).at(0).bytes) / (1 << 20);
  std::printf("first resting 720p session: %.1f MiB; each further one: %.1f MiB (shared voxels: %.1f MiB; "
              "a frame's scratch, shared: %.1f MiB)\n",
              free_before - free_one, free_one - free_two, voxels_mib,
              (free_before - free_one) - (free_one - free_two) - voxels_mib);
  EXPECT_EQ(CopiesOf(volume).size(), 1u);

  // The parts, one by one, as a session's pipeline makes them.
  const RenderSetup setup = ResolveScene(scene, *volume, nullptr);
  auto renderer = CreateRenderer(Backend::kCuda);
  renderer->SetVolume(volume);
  renderer->SetTransferFunction(setup.transfer_function);
  renderer->SetLights(setup.lights);
  FrameRequest request;
  request.camera = setup.camera;
  request.spp = setup.spp;
  const FrameScratchScope scratch(std::size_t(request.camera.width) * request.camera.height);  // as a session's frame
  const double before_renderer = free_mib();
  renderer->Render(request);
  renderer->LastFrameMilliseconds();
  const double after_renderer = free_mib();
  auto denoiser = CreateDenoiser(Backend::kCuda, FrameSettings{}.denoiser);
  const FrameTargets targets = renderer->Targets();
  DenoiseFrame frame;
  frame.width = setup.camera.width;
  frame.height = setup.camera.height;
  frame.radiance = targets.radiance;
  frame.first_hit = targets.first_hit;
  frame.albedo = targets.albedo;
  frame.camera = setup.camera;
  denoiser->Denoise(frame);
  const double after_denoiser = free_mib();
  const double renderer_mib = before_renderer - after_renderer, denoiser_mib = after_renderer - after_denoiser;
  std::printf("of a session: renderer %.1f MiB, denoiser (%s) %.1f MiB, the rest of the pipeline %.1f MiB\n",
              renderer_mib, ToString(FrameSettings{}.denoiser.method), denoiser_mib,
              (free_one - free_two) - renderer_mib - denoiser_mib);
}
#endif

}  // namespace
}  // namespace cinevol
