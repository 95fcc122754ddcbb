// FramePipeline: scene diffing, the per-frame chain and refinement.
#include "pipeline/frame_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>

namespace cinevol {
namespace {

using Clock = std::chrono::steady_clock;

double MillisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// The camera of the same view over a fraction of the pixels.
Camera Scaled(Camera camera, float scale) {
  if (scale == 1.0f) return camera;
  camera.width = std::max(1, static_cast<int>(std::lround(float(camera.width) * scale)));
  camera.height = std::max(1, static_cast<int>(std::lround(float(camera.height) * scale)));
  return camera;
}

}  // namespace

FramePipeline::FramePipeline(Backend backend, std::shared_ptr<const Volume> volume, const RendererOptions& options,
                             std::shared_ptr<const LabelVolume> labels)
    : volume_(std::move(volume)), labels_(std::move(labels)), renderer_(CreateRenderer(backend, options)) {
  renderer_->SetVolume(volume_);
#if CINEVOL_WITH_CUDA
  if (renderer_->backend() == Backend::kCuda) {
    display_ = MakeCudaDisplay();
    upsampler_ = MakeCudaUpsampler();
    refiner_ = MakeCudaRefiner();
  }
#endif
  if (!display_) {
    display_ = MakeCpuDisplay();
    upsampler_ = MakeCpuUpsampler();
    refiner_ = MakeCpuRefiner();
  }
}

FramePipeline::~FramePipeline() = default;

void FramePipeline::Update(const v1::Scene& scene, const FrameSettings& settings, unsigned changes) {
  if (!has_scene_) changes = kEverythingChanged;
  // Named views frame what the transfer function and the labels show and the
  // clipping keeps, so they follow their edits.
  if ((changes & (kTransferFunctionChanged | kClippingChanged | kLabelsChanged)) &&
      scene.camera().view() != v1::NAMED_VIEW_UNSPECIFIED) {
    changes |= kCameraChanged;
  }
  if (changes & kTransferFunctionChanged) {
    SetTransferFunction(ResolveTransferFunction(scene.transfer_function(), *volume_));
  }
  if (changes & kLightsChanged) renderer_->SetLights(ResolveLights(scene.lights(), cancel_));
  if (changes & kClippingChanged) {
    clip_ = ResolveClipping(scene.clipping(), *volume_);
    renderer_->SetClipRegion(clip_);
  }
  if (changes & kLabelsChanged) {
    SetLabels(ResolveLabels(scene.labels(), *volume_));
  }
  if (changes & kSamplingChanged) renderer_->SetReconstruction(ResolveReconstruction(scene.render().reconstruction()));
  if (changes & kCameraChanged) {
    camera_ = ResolveCamera(scene.camera(), scene.render(), *volume_, transfer_function_,
                            {clip_, labels_ ? &label_blocks_ : nullptr});
  }
  spp_ = static_cast<int>(scene.render().spp());
  max_bounces_ = static_cast<int>(scene.render().max_bounces());
  seed_ = scene.render().seed();
  exposure_ = scene.camera().exposure();
  Apply(settings, changes);
}

void FramePipeline::Update(const RenderSetup& setup, const FrameSettings& settings, unsigned changes) {
  if (!has_scene_) changes = kEverythingChanged;
  if (changes & kTransferFunctionChanged) SetTransferFunction(setup.transfer_function);
  if (changes & kLightsChanged) renderer_->SetLights(setup.lights);
  if (changes & kClippingChanged) {
    clip_ = setup.clip;
    renderer_->SetClipRegion(clip_);
  }
  if (changes & kLabelsChanged) SetLabels(setup.labels);
  if (changes & kSamplingChanged) renderer_->SetReconstruction(setup.reconstruction);
  if (changes & kCameraChanged) camera_ = setup.camera;
  spp_ = setup.spp;
  max_bounces_ = setup.max_bounces;
  seed_ = setup.seed;
  exposure_ = setup.exposure;
  Apply(settings, changes);
}

void FramePipeline::SetLabels(const LabelSetup& setup) {
  renderer_->SetLabels(labels_, setup);
  if (labels_) label_blocks_ = BlocksWithVisibleLabels(*volume_, *labels_, setup);  // for framing
}

void FramePipeline::SetTransferFunction(TransferFunction tf) {
  transfer_function_ = std::move(tf);
  renderer_->SetTransferFunction(transfer_function_);  // rebuilds the majorants
  ++transfer_function_builds_;
}

void FramePipeline::Apply(const FrameSettings& settings, unsigned changes) {
  if (!has_scene_ || !(settings.denoiser == settings_.denoiser)) {
    denoiser_ = CreateDenoiser(renderer_->backend(), settings.denoiser);  // frames stay in the renderer's memory
  }
  if (changes & (kTransferFunctionChanged | kLightsChanged | kClippingChanged | kLabelsChanged)) ++scene_version_;
  if (has_scene_ && (changes & (kCameraChanged | kTransferFunctionChanged))) moved_at_ = Clock::now();
  if (changes & kEverythingChanged) ResetAccumulation();
  settings_ = settings;
  has_scene_ = true;
}

float FramePipeline::ChooseScale() {
  const bool moving = settings_.interactive_frame_ms > 0 &&
                      Clock::now() - moved_at_ < std::chrono::milliseconds(kInteractionHoldMs);
  if (!moving) return 1.0f;
  if (scale_ != moving_scale_ || frame_times_ <= kFrameTimesPerStep) return moving_scale_;
  const float* scale = std::find(std::begin(kInteractiveScales), std::end(kInteractiveScales), scale_);
  const double budget = settings_.interactive_frame_ms;
  if (frame_ms_ > budget && scale + 1 != std::end(kInteractiveScales)) {
    moving_scale_ = scale[1];
  } else if (scale != std::begin(kInteractiveScales)) {
    // Up only with room to spare: the work is per pixel, and a larger size
    // that misses the budget would step straight back down.
    const double larger_ms = frame_ms_ * (scale[-1] * scale[-1]) / (scale_ * scale_);
    if (larger_ms < 0.8 * budget) moving_scale_ = scale[-1];
  }
  return moving_scale_;
}

void FramePipeline::SetScale(float scale) {
  if (scale == scale_) return;
  scale_ = scale;
  frame_times_ = 0;
  ResetAccumulation();
}

void FramePipeline::ResetAccumulation() {
  renderer_->ResetAccumulation();
  accumulated_spp_ = 0;
  estimated_error_ = -1;
}

ImageRgbF FramePipeline::RefinedRadiance() const { return last_frame_blended_ ? refiner_->Output() : ImageRgbF{}; }

bool FramePipeline::Converged() const {
  if (scale_ != 1.0f) return false;
  if (accumulated_spp_ >= settings_.target_spp) return true;
  return settings_.refine && settings_.error_target > 0 && estimated_error_ >= 0 &&
         estimated_error_ <= settings_.error_target;
}

void FramePipeline::MeasureFrameTime(Clock::time_point start) {
  if (!last_frame_final_) {
    const double ms = std::chrono::duration<double, std::milli>(start - last_frame_start_).count();
    if (frame_times_ > 0) frame_ms_ = frame_times_ == 1 ? ms : 0.7 * frame_ms_ + 0.3 * ms;
    ++frame_times_;
  }
  last_frame_start_ = start;
}

FrameRequest FramePipeline::Request(int spp) {
  FrameRequest r;
  r.camera = Scaled(camera_, scale_);
  r.spp = spp;
  r.max_bounces = max_bounces_;
  r.seed = seed_;
  r.frame = frame_++;
  r.features = render_features_;
  r.cancel = cancel_;
  return r;
}

DisplayFrame FramePipeline::RenderFrame() {
  if (!has_scene_) throw std::logic_error("FramePipeline::RenderFrame before Update");
  MeasureFrameTime(Clock::now());
  SetScale(ChooseScale());
  DisplayFrame out;
  out.resolution_scale = scale_;
  last_frame_blended_ = false;
  const FrameRequest request = Request(spp_);
  const Camera& camera = request.camera;
  renderer_->Render(request);
  out.render_ms = renderer_->LastFrameMilliseconds();
  accumulated_spp_ += spp_;

  const FrameTargets t = renderer_->Targets();
  const Vec3f* denoised =
      denoiser_->Denoise({camera.width, camera.height, t.radiance, t.first_hit, t.albedo, camera, scene_version_});
  out.denoise_ms = denoiser_->LastMilliseconds();

  const auto display_start = Clock::now();
  DisplayInputs in;
  in.width = camera_.width;
  in.height = camera_.height;
  in.exposure = exposure();
  if (scale_ < 1.0f) {
    // A moving view shows the denoiser's output alone: its few samples are
    // about to be replaced.
    in.radiance = upsampler_->Run(denoised, camera.width, camera.height, camera_.width, camera_.height);
  } else if (settings_.refine) {
    // The denoiser's output and the mean of the frames so far, combined per
    // pixel by their estimated errors.
    const RefinedImage refined = refiner_->Refine(
        {camera.width, camera.height, t.radiance, t.accumulated, denoised, renderer_->accumulated_frames(), exposure_});
    in.radiance = refined.radiance;
    last_frame_blended_ = refined.estimated_error >= 0;
    estimated_error_ = refined.estimated_error;
    out.estimated_error = refined.estimated_error;
  } else {
    in.radiance = denoised;
  }
  in.chroma = settings_.chroma;
  out.accumulated_spp = accumulated_spp_;
  out.final = Converged();
  last_frame_final_ = out.final;
  if (out.final && settings_.final_png) {
    out.final_rgb = display_->RunRgb(in);
  } else {
    out.image = display_->Run(in);
  }
  out.display_ms = MillisecondsSince(display_start);
  return out;
}

void FramePipeline::Accumulate(int spp) {
  if (!has_scene_) throw std::logic_error("FramePipeline::Accumulate before Update");
  SetScale(1.0f);
  renderer_->Render(Request(spp));
  accumulated_spp_ += spp;
}

}  // namespace cinevol
