// FramePipeline: scene diffing, the per-frame chain and refinement.
#include "pipeline/frame_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <optional>
#include <stdexcept>

#include "core/error.h"
#include "device/frame_scratch.h"
#include "io/reader_cage.h"

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

namespace {

constexpr std::pair<v1::Denoiser, DenoiseMethod> kDenoisers[] = {
    {v1::DENOISER_NONE, DenoiseMethod::kNone}, {v1::DENOISER_ACCUMULATE, DenoiseMethod::kAccumulate},
    {v1::DENOISER_KNN, DenoiseMethod::kKnn},   {v1::DENOISER_GUIDED, DenoiseMethod::kGuidedFilter},
    {v1::DENOISER_SVGF, DenoiseMethod::kSvgf}, {v1::DENOISER_WRLS, DenoiseMethod::kWrls},
};
constexpr std::pair<v1::ChromaSubsampling, ChromaSubsampling> kChromas[] = {
    {v1::CHROMA_444, ChromaSubsampling::k444},
    {v1::CHROMA_422, ChromaSubsampling::k422},
    {v1::CHROMA_420, ChromaSubsampling::k420},
};

}  // namespace

FrameSettings SessionFrameSettings(Backend backend, const v1::StreamSettings& stream) {
  FrameSettings s;
  if (backend == Backend::kCpu) s.interactive_frame_ms = kCpuInteractiveFrameMs;
  for (auto [proto, method] : kDenoisers) {
    if (stream.denoiser() == proto) s.denoiser.method = method;
  }
  for (auto [proto, chroma] : kChromas) {
    if (stream.chroma() == proto) s.chroma = chroma;
  }
  if (stream.final_format() != v1::FINAL_FORMAT_UNSPECIFIED)
    s.final_png = stream.final_format() == v1::FINAL_FORMAT_PNG;
  if (stream.has_demodulate()) s.denoiser.demodulate = stream.demodulate();
  if (stream.has_jpeg_quality()) s.jpeg_quality = int(stream.jpeg_quality());
  if (stream.has_final_jpeg_quality()) s.final_jpeg_quality = int(stream.final_jpeg_quality());
  if (stream.has_target_spp()) s.target_spp = int(stream.target_spp());
  if (stream.has_interactive_frame_ms()) s.interactive_frame_ms = stream.interactive_frame_ms();
  if (stream.has_frames_at_rendered_size()) s.frames_at_rendered_size = stream.frames_at_rendered_size();
  if (stream.has_error_target()) s.error_target = stream.error_target();
  return s;
}

v1::StreamSettings ToStreamSettings(const FrameSettings& s) {
  v1::StreamSettings stream;
  for (auto [proto, method] : kDenoisers) {
    if (s.denoiser.method == method) stream.set_denoiser(proto);
  }
  for (auto [proto, chroma] : kChromas) {
    if (s.chroma == chroma) stream.set_chroma(proto);
  }
  stream.set_final_format(s.final_png ? v1::FINAL_FORMAT_PNG : v1::FINAL_FORMAT_JPEG);
  stream.set_demodulate(s.denoiser.demodulate);
  stream.set_jpeg_quality(std::uint32_t(s.jpeg_quality));
  stream.set_final_jpeg_quality(std::uint32_t(s.final_jpeg_quality));
  stream.set_target_spp(std::uint32_t(s.target_spp));
  stream.set_interactive_frame_ms(s.interactive_frame_ms);
  stream.set_frames_at_rendered_size(s.frames_at_rendered_size);
  stream.set_error_target(s.error_target);
  return stream;
}

FramePipeline::FramePipeline(Backend backend, std::shared_ptr<const Volume> volume, const RendererOptions& options,
                             std::shared_ptr<const LabelVolume> labels)
    : volume_(std::move(volume)), labels_(std::move(labels)), renderer_(CreateRenderer(backend, options)) {
  renderer_->SetVolume(volume_);
  policy_ = renderer_->backend() == Backend::kCpu ? InteractivePolicy::kCostModel : InteractivePolicy::kSteps;
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

void FramePipeline::SetJpegEncoder(JpegEncoderKind kind) {
  device_jpeg_.reset();
  if (kind == JpegEncoderKind::kCpu) return;
  if (kind == JpegEncoderKind::kAuto) throw std::logic_error("SetJpegEncoder takes ChooseJpegEncoder's choice");
  const char* flag = kind == JpegEncoderKind::kCuda ? "--jpeg-encoder cuda" : "--jpeg-encoder nvjpeg";
  if (renderer_->backend() != Backend::kCuda) throw InputError(std::string(flag) + ": frames render on the CPU");
#if CINEVOL_WITH_CUDA
  if (kind == JpegEncoderKind::kCuda) {
    device_jpeg_ = MakeCudaJpegEncoder();
    return;
  }
  const NvjpegLookup& nvjpeg = ProcessNvjpeg();
  if (!nvjpeg.library) throw InputError(std::string(flag) + ": " + nvjpeg.why_not);
  device_jpeg_ = MakeNvjpegEncoder(nvjpeg.library);
#endif
}

void FramePipeline::Update(const v1::Scene& scene, const FrameSettings& settings, unsigned changes) {
  if (!has_scene_) changes = kEverythingChanged;
  if (changes & kTransferFunctionChanged) {
    SetTransferFunction(ResolveTransferFunction(scene.transfer_function(), *volume_));
  }
  if (changes & kLightsChanged) {
    renderer_->SetLights(ResolveLights(
        scene.lights(), [this](const std::string& map) { return reader_cage::ReadEnvironmentMap(map, cancel_); }));
  }
  if (changes & kClippingChanged) {
    clip_ = ResolveClipping(scene.clipping(), *volume_);
    renderer_->SetClipRegion(clip_);
  }
  if (changes & kLabelsChanged) {
    SetLabels(ResolveLabels(scene.labels(), *volume_));
  }
  if (changes & kSamplingChanged) renderer_->SetReconstruction(ResolveReconstruction(scene.render().reconstruction()));
  if (changes & kFusionChanged) {
    const bool fused = scene.has_fusion() && fused_;
    renderer_->SetFusion(fused ? fused_ : nullptr,
                         fused ? ResolveFusion(scene.fusion(), *volume_, *fused_) : FusionSetup{});
  }
  if (changes &
      kCameraChanged) {  // sessions send numbers; a named view here frames what the TF shows and the clipping keeps
    camera_ = ResolveCamera(scene.camera(), scene.render(), *volume_, transfer_function_, {clip_});
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
  if (changes & kFusionChanged) renderer_->SetFusion(setup.fused_volume, setup.fusion);
  if (changes & kCameraChanged) camera_ = setup.camera;
  spp_ = setup.spp;
  max_bounces_ = setup.max_bounces;
  seed_ = setup.seed;
  exposure_ = setup.exposure;
  Apply(settings, changes);
}

void FramePipeline::SetLabels(const LabelSetup& setup) {
  label_setup_ = setup;
  renderer_->SetLabels(labels_, setup);
}

void FramePipeline::SetPhase(std::shared_ptr<const Volume> phase) {
  if (phase == volume_) return;
  if (phase->dims() != volume_->dims()) throw std::invalid_argument("FramePipeline::SetPhase: another grid");
  volume_ = std::move(phase);
  renderer_->SetVolume(volume_);  // forgets the segmentation and the tables: set again
  if (!has_scene_) return;        // the first Update sets them
  renderer_->SetTransferFunction(transfer_function_);
  renderer_->SetLabels(labels_, label_setup_);
  ++scene_version_;
  ResetAccumulation();  // the samples so far are another phase's
  if (settings_.phase_history == PhaseHistory::kReset)
    denoiser_ = CreateDenoiser(renderer_->backend(), settings_.denoiser);
  if (settings_.phase_history != PhaseHistory::kKept) picture_changed_ = shading_changed_ = true;
}

void FramePipeline::SetTransferFunction(TransferFunction tf) {
  transfer_function_ = std::move(tf);
  renderer_->SetTransferFunction(transfer_function_);  // rebuilds the majorants
  ++transfer_function_builds_;
}

void FramePipeline::Apply(const FrameSettings& settings, unsigned changes) {
  if (!has_scene_ || settings.denoiser != settings_.denoiser) {
    denoiser_ = CreateDenoiser(renderer_->backend(), settings.denoiser);  // frames stay in the renderer's memory
  }
  if (changes & (kTransferFunctionChanged | kLightsChanged | kClippingChanged | kLabelsChanged | kFusionChanged)) {
    ++scene_version_;
  }
  picture_changed_ |= (changes & kPictureChanges) != 0;
  shading_changed_ |= (changes & kPictureChanges & ~kCameraChanged) != 0;
  // On the CPU every edit of the picture is an interaction: a full-size
  // frame after a moved light would take seconds.
  const unsigned interactions = policy_ == InteractivePolicy::kCostModel
                                    ? (kCameraChanged | kTransferFunctionChanged | kLightsChanged | kClippingChanged |
                                       kLabelsChanged | kFusionChanged)
                                    : (kCameraChanged | kTransferFunctionChanged);
  if (has_scene_ && (changes & interactions)) moved_at_ = Clock::now();
  if (changes & kEverythingChanged) ResetAccumulation();
  settings_ = settings;
  has_scene_ = true;
}

bool FramePipeline::Moving() const {
  return settings_.interactive_frame_ms > 0 && Clock::now() - moved_at_ < std::chrono::milliseconds(kInteractionHoldMs);
}

float FramePipeline::ChooseScale() {
  if (!Moving()) return 1.0f;
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

int FramePipeline::ChooseCostModelFrame(bool moving) {
  const std::int64_t viewport = std::int64_t(camera_.width) * camera_.height;
  if (moving) {
    const MovingFrame next = ChooseMovingFrame(cost_, viewport, spp_, settings_.interactive_frame_ms,
                                               {moving_scale_, moving_spp_}, settings_.frames_at_rendered_size);
    moving_scale_ = next.scale;
    moving_spp_ = next.spp;
    SetScale(next.scale);
    return next.spp;
  }
  SetScale(1.0f);
  if (!LiveOnCpu() || !settings_.refine) return spp_;
  still_spp_ = ChooseStillSpp(cost_, viewport, spp_, still_spp_);
  // Not past the refinement's cap.
  return std::clamp(settings_.target_spp - accumulated_spp_, 1, still_spp_);
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
  still_spp_ = 0;
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
    cost_.ObserveInterval(ms);
  }
  last_frame_start_ = start;
}

std::optional<FrameScratchScope> FramePipeline::GpuFrameScratch(const Camera& camera) const {
  if (renderer_->backend() != Backend::kCuda) return std::nullopt;  // a CPU thread keeps its own
  return std::optional<FrameScratchScope>(std::in_place, std::size_t(camera.width) * camera.height);
}

FrameRequest FramePipeline::Request(int spp) {
  FrameRequest r;
  r.camera = Scaled(camera_, scale_);
  r.spp = spp;
  r.max_bounces = max_bounces_;
  r.seed = seed_;
  r.frame = frame_++;
  r.features = render_features_;
  r.surface_normals = UsesSurfaceNormals(settings_.denoiser);
  r.cancel = cancel_;
  return r;
}

DisplayFrame FramePipeline::RenderFrame() {
  if (!has_scene_) throw std::logic_error("FramePipeline::RenderFrame before Update");
  MeasureFrameTime(Clock::now());
  int spp = spp_;
  const bool moving = Moving();
  if (policy_ == InteractivePolicy::kCostModel) {
    spp = ChooseCostModelFrame(moving);
  } else {
    SetScale(ChooseScale());
  }
  DisplayFrame out;
  out.resolution_scale = scale_;
  out.spp = spp;
  last_frame_blended_ = false;
  FrameRequest request = Request(spp);
  if (!moving && LiveOnCpu()) request.preempt = preempt_;  // moving frames are what events wait for
  const Camera& camera = request.camera;
  const auto scratch = GpuFrameScratch(camera);
  try {
    renderer_->Render(request);
  } catch (const FramePreempted&) {
    ResetAccumulation();       // it holds part of the frame
    last_frame_final_ = true;  // the next frame follows an event: no frame time
    out.preempted = true;
    return out;
  }
  accumulated_spp_ += spp;

  const FrameTargets t = renderer_->Targets();
  const bool only_moved = picture_changed_ && !std::exchange(shading_changed_, false);
  const Vec3f* denoised = denoiser_->Denoise({camera.width, camera.height, t.radiance, t.first_hit, t.albedo, camera,
                                              std::exchange(picture_changed_, false), only_moved, t.surface_normal});
  out.denoise_ms = denoiser_->LastMilliseconds();

  const auto display_start = Clock::now();
  double refine_ms = 0;
  out.width = camera_.width;
  out.height = camera_.height;
  // A smaller frame is upsampled here unless its client stretches it.
  const bool smaller = scale_ < 1.0f;
  const bool upsample = smaller && !settings_.frames_at_rendered_size;
  const bool upsample_in_display = upsample && renderer_->backend() == Backend::kCpu;  // no viewport-sized buffer
  DisplayInputs in;
  in.width = upsample ? camera_.width : camera.width;
  in.height = upsample ? camera_.height : camera.height;
  in.exposure = exposure();
  if (smaller) {
    // A moving view shows the denoiser's output alone: its few samples are
    // about to be replaced.
    if (!upsample) {
      in.radiance = denoised;
    } else if (!upsample_in_display) {
      in.radiance = upsampler_->Run(denoised, camera.width, camera.height, camera_.width, camera_.height);
    }
  } else if (settings_.refine) {
    // The denoiser's output and the mean of the samples so far, combined per
    // pixel by their estimated errors.
    const auto refine_start = Clock::now();
    const RefinedImage refined = refiner_->Refine(
        {camera.width, camera.height, t.radiance, t.accumulated, denoised, renderer_->accumulated_frames(), exposure_,
         spp, accumulated_spp_});
    refine_ms = MillisecondsSince(refine_start);
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
  out.jpeg_quality = out.final ? settings_.final_jpeg_quality : settings_.jpeg_quality;
  in.hold_codes = settings_.hold_codes && !out.final;
  last_frame_final_ = out.final;
  if (out.final && settings_.final_png) {
    out.final_rgb = display_->RunRgb(in);
  } else if (upsample_in_display) {
    out.image = display_->RunUpsampled(in, denoised, camera.width, camera.height);
  } else if (device_jpeg_) {
    out.jpeg = display_->RunJpeg(in, *device_jpeg_, out.jpeg_quality);
    out.encode_ms = device_jpeg_->LastMilliseconds();
    if (out.jpeg.bytes.empty()) out.image = display_->LastPlanes();  // given back: the host encodes it
  } else {
    out.image = display_->Run(in);
  }
  out.display_ms = MillisecondsSince(display_start) - out.encode_ms;
  // Read once the frame is done: reading it sooner would wait for the render
  // before the denoiser's passes are queued behind it.
  out.render_ms = renderer_->LastFrameMilliseconds();
  cost_.Observe({std::int64_t(camera.width) * camera.height, std::int64_t(in.width) * in.height, spp, out.render_ms,
                 out.denoise_ms, out.display_ms - refine_ms, refine_ms});
  return out;
}

void FramePipeline::Accumulate(int spp) {
  if (!has_scene_) throw std::logic_error("FramePipeline::Accumulate before Update");
  SetScale(1.0f);
  const FrameRequest request = Request(spp);
  const auto scratch = GpuFrameScratch(request.camera);
  renderer_->Render(request);
  accumulated_spp_ += spp;
}

}  // namespace cinevol
