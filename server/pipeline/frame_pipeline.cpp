// FramePipeline: scene diffing, the per-frame chain and refinement blending.
#include "pipeline/frame_pipeline.h"

#include <chrono>
#include <cmath>

#include "io/scene_builder.h"

namespace cinevol {
namespace {

bool SameDenoiser(const FrameSettings& a, const FrameSettings& b) {
  return a.denoiser == b.denoiser && a.demodulate == b.demodulate;
}

double MillisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
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
  if (renderer_->backend() == Backend::kCuda) display_ = MakeCudaDisplay();
#endif
  if (!display_) display_ = MakeCpuDisplay();
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
  if (tf_changed || lights_changed || camera_changed || sampling_changed) {
    renderer_->ResetAccumulation();
    accumulated_spp_ = 0;
  }
  scene_ = scene;
  settings_ = settings;
  has_scene_ = true;
}

FrameRequest FramePipeline::Request(int spp) {
  FrameRequest r;
  r.camera = camera_;
  r.spp = spp;
  r.max_bounces = static_cast<int>(scene_.render().max_bounces());
  r.seed = scene_.render().seed();
  r.frame = frame_++;
  r.cancel = cancel_;
  return r;
}

DisplayFrame FramePipeline::RenderFrame() {
  if (!has_scene_) throw std::logic_error("FramePipeline::RenderFrame before Update");
  DisplayFrame out;
  const int spp = static_cast<int>(scene_.render().spp());
  renderer_->Render(Request(spp));
  out.render_ms = renderer_->LastFrameMilliseconds();
  accumulated_spp_ += spp;

  const FrameTargets t = renderer_->Targets();
  const Vec3f* denoised =
      denoiser_->Denoise({camera_.width, camera_.height, t.radiance, t.first_hit, t.albedo, camera_, scene_version_});
  out.denoise_ms = denoiser_->LastMilliseconds();

  const auto display_start = std::chrono::steady_clock::now();
  DisplayInputs in;
  in.width = camera_.width;
  in.height = camera_.height;
  in.denoised = denoised;
  in.accumulated_sum = t.accumulated;
  in.inv_frames = 1.0f / float(renderer_->accumulated_frames());
  in.blend = RefinementBlend(accumulated_spp_, settings_.target_spp);
  in.exposure = exposure();
  in.chroma = settings_.chroma;
  out.image = display_->Run(in);
  out.display_ms = MillisecondsSince(display_start);
  out.accumulated_spp = accumulated_spp_;
  out.final = Converged();
  return out;
}

void FramePipeline::Accumulate(int spp) {
  if (!has_scene_) throw std::logic_error("FramePipeline::Accumulate before Update");
  renderer_->Render(Request(spp));
  accumulated_spp_ += spp;
}

}  // namespace cinevol
