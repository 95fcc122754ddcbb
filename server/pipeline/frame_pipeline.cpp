// FramePipeline: scene diffing, the per-frame chain and refinement blending.
#include "pipeline/frame_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>

#include "io/scene_builder.h"

namespace cinevol {
namespace {

bool SameDenoiser(const FrameSettings& a, const FrameSettings& b) {
  return a.denoiser == b.denoiser && a.demodulate == b.demodulate;
}

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

float RefinementBlend(int accumulated_spp, int target_spp) {
  if (accumulated_spp >= target_spp) return 1.0f;
  if (accumulated_spp <= kBlendStartSpp) return 0.0f;
  return std::log(float(accumulated_spp) / kBlendStartSpp) / std::log(float(target_spp) / kBlendStartSpp);
}

FramePipeline::FramePipeline(Backend backend, std::shared_ptr<const Volume> volume)
    : volume_(std::move(volume)), renderer_(CreateRenderer(backend)) {
  renderer_->SetVolume(volume_);
#if CINEVOL_WITH_CUDA
  if (renderer_->backend() == Backend::kCuda) {
    display_ = MakeCudaDisplay();
    upsampler_ = MakeCudaUpsampler();
  }
#endif
  if (!display_) {
    display_ = MakeCpuDisplay();
    upsampler_ = MakeCpuUpsampler();
  }
}

FramePipeline::~FramePipeline() = default;

void FramePipeline::Update(const v1::Scene& scene, const FrameSettings& settings, unsigned changes) {
  const bool first = !has_scene_;
  if (first) changes = kEverythingChanged;
  const bool tf_changed = changes & kTransferFunctionChanged;
  const bool lights_changed = changes & kLightsChanged;
  // Named views frame what the transfer function shows, so they follow its edits.
  const bool camera_changed =
      (changes & kCameraChanged) || (tf_changed && scene.camera().view() != v1::NAMED_VIEW_UNSPECIFIED);
  const bool sampling_changed = changes & kSamplingChanged;

  if (tf_changed) {
    transfer_function_ = ResolveTransferFunction(scene.transfer_function(), *volume_);
    renderer_->SetTransferFunction(transfer_function_);
  }
  if (lights_changed) renderer_->SetLights(ResolveLights(scene.lights()));
  if (camera_changed) camera_ = ResolveCamera(scene.camera(), scene.render(), *volume_, transfer_function_);
  if (first || !SameDenoiser(settings, settings_)) {
    DenoiserSettings denoiser;
    denoiser.method = settings.denoiser;
    denoiser.demodulate = settings.demodulate;
    denoiser_ = CreateDenoiser(renderer_->backend(), denoiser);  // frames stay in the renderer's memory
  }
  if (tf_changed || lights_changed) ++scene_version_;
  if (!first && (camera_changed || tf_changed)) moved_at_ = Clock::now();
  if (tf_changed || lights_changed || camera_changed || sampling_changed) {
    renderer_->ResetAccumulation();
    accumulated_spp_ = 0;
  }
  scene_ = scene;
  settings_ = settings;
  has_scene_ = true;
}

float FramePipeline::ChooseScale() {
  const bool moving = settings_.interactive_frame_ms > 0 &&
                      Clock::now() - moved_at_ < std::chrono::milliseconds(kInteractionHoldMs);
  if (!moving || full_size_ms_ <= 0) return 1.0f;
  // A smaller scale holds until the view stops: each new size restarts the
  // denoiser's history.
  if (scale_ < 1.0f) return scale_;
  for (const float scale : kInteractiveScales) {
    if (full_size_ms_ * scale * scale <= settings_.interactive_frame_ms) return scale;
  }
  return std::end(kInteractiveScales)[-1];
}

void FramePipeline::SetScale(float scale) {
  if (scale == scale_) return;
  scale_ = scale;
  renderer_->ResetAccumulation();
  accumulated_spp_ = 0;
}

FrameRequest FramePipeline::Request(int spp) {
  FrameRequest r;
  r.camera = Scaled(camera_, scale_);
  r.spp = spp;
  r.max_bounces = static_cast<int>(scene_.render().max_bounces());
  r.seed = scene_.render().seed();
  r.frame = frame_++;
  r.cancel = cancel_;
  return r;
}

DisplayFrame FramePipeline::RenderFrame() {
  if (!has_scene_) throw std::logic_error("FramePipeline::RenderFrame before Update");
  SetScale(ChooseScale());
  DisplayFrame out;
  out.resolution_scale = scale_;
  const int spp = static_cast<int>(scene_.render().spp());
  const FrameRequest request = Request(spp);
  const Camera& camera = request.camera;
  renderer_->Render(request);
  out.render_ms = renderer_->LastFrameMilliseconds();
  accumulated_spp_ += spp;

  const FrameTargets t = renderer_->Targets();
  const Vec3f* denoised =
      denoiser_->Denoise({camera.width, camera.height, t.radiance, t.first_hit, t.albedo, camera, scene_version_});
  out.denoise_ms = denoiser_->LastMilliseconds();
  const double full_size_ms = (out.render_ms + out.denoise_ms) / (scale_ * scale_);
  full_size_ms_ = full_size_ms_ > 0 ? 0.75 * full_size_ms_ + 0.25 * full_size_ms : full_size_ms;

  const auto display_start = Clock::now();
  DisplayInputs in;
  in.width = camera_.width;
  in.height = camera_.height;
  in.exposure = exposure();
  if (scale_ < 1.0f) {
    // A moving view shows the denoiser's output alone: its few samples are
    // about to be replaced.
    in.denoised = upsampler_->Run(denoised, camera.width, camera.height, camera_.width, camera_.height);
  } else {
    in.denoised = denoised;
    in.accumulated_sum = t.accumulated;
    in.inv_frames = 1.0f / float(renderer_->accumulated_frames());
    in.blend = RefinementBlend(accumulated_spp_, settings_.target_spp);
  }
  in.chroma = settings_.chroma;
  out.image = display_->Run(in);
  out.display_ms = MillisecondsSince(display_start);
  out.accumulated_spp = accumulated_spp_;
  out.final = Converged();
  return out;
}

void FramePipeline::Accumulate(int spp) {
  if (!has_scene_) throw std::logic_error("FramePipeline::Accumulate before Update");
  SetScale(1.0f);
  renderer_->Render(Request(spp));
  accumulated_spp_ += spp;
}

}  // namespace cinevol
