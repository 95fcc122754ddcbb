// The renderer interface: one path tracer behind a CPU and a CUDA backend.
// Scene parts are set when they change (the volume rarely, the transfer
// function and lights on edits); Render draws one frame of spp samples per
// pixel and adds it to the running accumulation.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/camera.h"
#include "core/clip_region.h"
#include "core/image.h"
#include "core/labels.h"
#include "core/lights.h"
#include "core/transfer_function.h"
#include "core/volume.h"
#include "device/device.h"
#include "render/render_scene.h"
#include "render/scene_data.h"

namespace cinevol {

// Bumped whenever the integrator's output changes: keys cached reference images.
inline constexpr int kRendererVersion = 2;  // 2: free-flight steps from the segment start, extinction clamp

// Picks the smallest specialised integrator for the scene.
inline constexpr unsigned kAutoFeatures = ~0u;

struct FrameRequest {
  Camera camera;        // its width and height set the frame size
  int spp = 1;          // samples per pixel in this frame, >= 1
  int max_bounces = 4;  // scattering events per path, >= 0
  std::uint64_t seed = 0;
  std::uint32_t frame = 0;            // advance every frame: seeds this frame's samples
  unsigned features = kAutoFeatures;  // or a RenderFeature set to force (at least what the scene uses)
  bool surface_normals = false;       // also FrameTargets::surface_normal (a denoiser's normal stop)
  // When set and raised, the CPU backend stops within a pixel and
  // Render throws Cancelled (the accumulation is then unusable). CUDA frames
  // are bounded by the service's per-frame sample limit instead.
  const std::atomic<bool>* cancel = nullptr;
  // When set and raised, the CPU backend stops within a pixel and Render
  // throws FramePreempted: a newer event makes this frame moot (a still
  // frame on the CPU takes seconds). The accumulation holds part of the
  // frame: reset it. CUDA frames ignore it (they take milliseconds).
  const std::atomic<bool>* preempt = nullptr;
};

// A frame stopped by FrameRequest::preempt.
class FramePreempted : public std::runtime_error {
 public:
  FramePreempted() : std::runtime_error("the frame was preempted by a newer event") {}
};

// Puts the request's camera and sampling into `scene` (whose views the
// backend has set) and returns the feature set to render it with: the
// smallest the scene needs, or the requested set plus what the scene needs.
inline unsigned ApplyRequest(const FrameRequest& request, RenderScene& scene) {
  scene.camera = request.camera;
  scene.spp = request.spp;
  scene.max_bounces = request.max_bounces;
  scene.seed = request.seed;
  scene.frame = request.frame;
  const unsigned needed = FeaturesOf(scene);
  const unsigned f = request.features == kAutoFeatures ? needed : (request.features & kAllFeatures) | needed;
  return VariantFeatures(VariantOf(f));  // clinical features come with every other
}

class Renderer {
 public:
  virtual ~Renderer() = default;
  virtual Backend backend() const = 0;  // kCpu or kCuda

  // The Volume must stay alive and unchanged while the renderer uses it.
  virtual void SetVolume(std::shared_ptr<const Volume> volume) = 0;
  virtual void SetTransferFunction(const TransferFunction& tf) = 0;
  virtual void SetLights(const LightSetup& lights) = 0;
  // What the crop box and clip planes keep; an empty region keeps everything.
  virtual void SetClipRegion(const ClipRegion& clip) = 0;
  virtual void SetReconstruction(Reconstruction r) = 0;
  // A segmentation on the volume's grid (null: none) and how its labels show.
  virtual void SetLabels(std::shared_ptr<const LabelVolume> labels, const LabelSetup& setup) = 0;
  // A second volume fused with this one (null: none) and how it shows; it
  // must stay alive and unchanged while the renderer uses it.
  virtual void SetFusion(std::shared_ptr<const Volume> fused, const FusionSetup& setup) = 0;

  // Renders one frame. A new frame size resets the accumulation.
  virtual void Render(const FrameRequest& request) = 0;
  virtual void ResetAccumulation() = 0;
  virtual int accumulated_frames() const = 0;
  // The feature set the last frame was rendered with.
  virtual unsigned last_features() const = 0;
  // How many times the majorants were rebuilt (SceneData::majorant_builds).
  virtual std::uint64_t majorant_builds() const = 0;
  // Time the last frame took to render: wall time on the CPU, kernel time
  // (CUDA events) on the GPU, where reading it waits for the frame.
  virtual double LastFrameMilliseconds() const = 0;

  // The last frame's outputs, copied to the host. On the GPU the radiance,
  // first hits and albedo are the rendering thread's frame scratch
  // (device/frame_scratch.h): read them, and Targets(), on that thread
  // before it renders another frame.
  virtual ImageRgbF Radiance() const = 0;
  virtual ImageRgbF AccumulatedMean() const = 0;
  virtual std::vector<Vec4f> FirstHits() const = 0;
  virtual ImageRgbF Albedo() const = 0;
  // FrameTargets::surface_normal of the last frame; empty where it did not ask.
  virtual std::vector<Vec3f> SurfaceNormals() const = 0;

  // The last frame's outputs in the backend's own memory (host or device),
  // for the denoiser of the same backend.
  virtual FrameTargets Targets() const = 0;
};

struct RendererOptions {
  // Voxels per majorant-grid brick edge: bricks skip empty space and bound
  // dense space tightly. kAutoBrickSize: BrickSizeFor the volume's spacing;
  // 0: no bricks, one global majorant.
  int brick_size = kAutoBrickSize;
  // CUDA: sample the volume through the texture unit (device/volume_texture.h);
  // false reads the voxel buffer, as the CPU does (to measure what it buys).
  bool volume_texture = true;
  int cpu_threads = 0;  // 0: every hardware thread (or CINEVOL_THREADS)
};

// kAuto takes CUDA when a usable GPU is present, else the CPU. kCuda without
// a GPU (or a build without CUDA) throws InputError saying why.
std::unique_ptr<Renderer> CreateRenderer(Backend backend, const RendererOptions& options = {});

}  // namespace cinevol
