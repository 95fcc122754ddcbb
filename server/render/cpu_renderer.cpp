// CpuRenderer: a table of integrator variants, one per feature set, each
// running rows of pixels in parallel.
#include "render/cpu_renderer.h"

#include <array>
#include <chrono>
#include <stdexcept>
#include <utility>

#include "core/error.h"
#include "core/parallel_for.h"
#include "render/integrator.h"

namespace cinevol {
namespace {

// The flags a frame stops at: the session's cancel and a newer event's preempt.
struct StopFlags {
  const std::atomic<bool>* cancel;
  const std::atomic<bool>* preempt;

  bool Raised() const {
    return (cancel && cancel->load(std::memory_order_relaxed)) || (preempt && preempt->load(std::memory_order_relaxed));
  }
};

using RenderFrameFn = void (*)(const RenderScene&, const FrameTargets&, int threads, StopFlags stop);

template <unsigned kFeatures>
void RenderFrame(const RenderScene& scene, const FrameTargets& targets, int threads, StopFlags stop) {
  // Every pixel looks at the flags: a pixel costs at most spp paths of
  // bounded cost (integrator.h), so a cancel is seen within that.
  ParallelFor(
      scene.camera.height,
      [&](std::int64_t y) {
        for (int x = 0; x < scene.camera.width; ++x) {
          if (stop.Raised()) return;
          RenderPixel<kFeatures>(scene, x, int(y), targets);
        }
      },
      threads);
}

template <unsigned... kVariant>
constexpr std::array<RenderFrameFn, sizeof...(kVariant)> MakeVariants(std::integer_sequence<unsigned, kVariant...>) {
  return {&RenderFrame<VariantFeatures(kVariant)>...};
}

constexpr auto kVariants = MakeVariants(std::make_integer_sequence<unsigned, kIntegratorVariants>());

}  // namespace

void CpuRenderer::SetVolume(std::shared_ptr<const Volume> volume) {
  volume_ = VolumeCache::Get().Acquire(volume, brick_size_, kHostDevice);
  data_.SetVolume(volume_->prepared_ptr());
}

void CpuRenderer::SetLabels(std::shared_ptr<const LabelVolume> labels, const LabelSetup& setup) {
  // Labels that change nothing are not looked up (a CT's table while it shows).
  const bool used = labels && setup.ChangesAnything(*labels);
  data_.SetLabels(used ? VolumeCache::Get().AcquireLabels(labels, data_.volume().brick_size(), kHostDevice) : nullptr,
                  setup);
}

void CpuRenderer::SetFusion(std::shared_ptr<const Volume> fused, const FusionSetup& setup) {
  // Its bricks' ranges bound its extinction over each of the first volume's bricks (SceneData).
  fused_ = fused ? VolumeCache::Get().Acquire(fused, kAutoBrickSize, kHostDevice) : nullptr;
  data_.SetFusion(fused_ ? fused_->prepared_ptr() : nullptr, setup);
}

void CpuRenderer::Render(const FrameRequest& request) {
  if (!data_.has_volume()) throw std::logic_error("CpuRenderer::Render before SetVolume");
  const int w = request.camera.width, h = request.camera.height;
  if (w != width_ || h != height_) {
    width_ = w;
    height_ = h;
    radiance_.assign(std::size_t(w) * h, {});
    first_hit_.assign(std::size_t(w) * h, {});
    albedo_.assign(std::size_t(w) * h, {});
    accumulated_.resize(std::size_t(w) * h);
    ResetAccumulation();
  }
  if (request.surface_normals) {
    surface_normal_.resize(std::size_t(w) * h);
  } else {
    surface_normal_.clear();
  }
  RenderScene scene = data_.HostView();
  last_features_ = ApplyRequest(request, scene);
  const auto start = std::chrono::steady_clock::now();
  kVariants[VariantOf(last_features_)](scene, Targets(), threads_, {request.cancel, request.preempt});
  if (request.cancel && request.cancel->load()) throw Cancelled("the frame was cancelled");
  if (request.preempt && request.preempt->load()) throw FramePreempted();
  last_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  ++accumulated_frames_;
  accumulated_samples_ += request.spp;
}

void CpuRenderer::ResetAccumulation() {
  accumulated_frames_ = 0;
  accumulated_samples_ = 0;
}

ImageRgbF CpuRenderer::Radiance() const { return {width_, height_, radiance_}; }

ImageRgbF CpuRenderer::AccumulatedMean() const {
  if (accumulated_samples_ == 0) return {width_, height_, std::vector<Vec3f>(accumulated_.size())};
  ImageRgbF image{width_, height_, accumulated_};
  const float inv = float(1.0 / double(accumulated_samples_));
  for (Vec3f& p : image.pixels) p *= inv;
  return image;
}

FrameTargets CpuRenderer::Targets() const {
  auto* self = const_cast<CpuRenderer*>(this);
  return {self->radiance_.data(),
          self->first_hit_.data(),
          self->accumulated_.data(),
          self->albedo_.data(),
          self->surface_normal_.empty() ? nullptr : self->surface_normal_.data(),
          accumulated_frames_ == 0};
}

}  // namespace cinevol
