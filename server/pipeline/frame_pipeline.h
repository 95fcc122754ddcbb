// FramePipeline: the one chain that turns a session's scene into frames.
// Scene edits rebuild only what they invalidate (a transfer-function edit
// re-derives the majorants, a camera move does not); each frame renders the
// scene's spp, denoises, combines the denoised image with the accumulation
// per pixel by their estimated errors (idle refinement), tone maps and
// converts to JPEG's YCbCr planes on the device and copies them to pinned
// host memory, ready for EncodeJpeg on any thread (or, with SetJpegEncoder's
// nvJPEG, encodes them on the GPU and copies only the JPEG).
//
// The service drives one per session; `cinevol render` and the benches
// drive the same object. CUDA work goes to the calling thread's current GPU
// and default stream: construct and use a pipeline on the thread (or
// threads) bound to its GPU.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "core/camera.h"
#include "core/image.h"
#include "core/volume.h"
#include "denoise/denoiser.h"
#include "device/frame_scratch.h"
#include "encode/image_codecs.h"
#include "pipeline/display.h"
#include "pipeline/frame_cost.h"
#include "pipeline/jpeg_encoder.h"
#include "pipeline/refine.h"
#include "pipeline/upsample.h"
#include "render/renderer.h"
#include "scene/scene_builder.h"
#include "scene/scene_file.h"  // SceneChange: what an update changes, as the events that made it say

namespace cinevol {

// The frame-time budget a session on the CPU backend gets unless it asks
// otherwise (FrameSettings::interactive_frame_ms; the service's default): a
// frame every 70 ms while the view moves keeps a viewer beside the server
// at >= 10 fps with p95 event-to-frame latency under 250 ms on 2 cores
// (docs/performance.md). On a GPU the default stays 0 (full size).
inline constexpr float kCpuInteractiveFrameMs = 70;

// The default refinement error target: an estimated relative RMS error of
// 2%, where CThead, the MR head and the head phantom at 720p stand at 44.3
// to 45.6 dB, after 120 to 176 spp (docs/tradeoff.md, "Still frames").
inline constexpr float kDefaultErrorTarget = 0.02f;

// How frames are made from the scene, beyond what the scene model says.
// What a phase switch of a time series (FramePipeline::SetPhase) does to the
// denoiser's history. Measured against per-phase references on an H200 at
// 720p (docs/tradeoff.md, "A beating heart"): dropping it matches the other
// rules on a cardiac cine and is the only one that does not smear a ball
// moving two voxels a phase (2.8 dB ahead of kChanged, 11.5 of kKept).
enum class PhaseHistory {
  kReset,    // dropped: a new denoiser starts from the new phase's first frame (the default)
  kChanged,  // kept and reprojected, the denoiser told the picture changed, as after any edit
  kKept,     // kept as though only the samples changed
};

struct FrameSettings {
  DenoiserSettings denoiser;  // the method and every knob of it; a change makes a new denoiser
  PhaseHistory phase_history = PhaseHistory::kReset;
  int jpeg_quality = 80;        // [1, 100]
  int final_jpeg_quality = 95;  // [1, 100]: the frame that ends refinement
  bool final_png = false;       // the frame that ends refinement as lossless 8-bit sRGB instead
  ChromaSubsampling chroma = ChromaSubsampling::k420;
  int target_spp = 256;  // >= 1: refinement stops at this many samples per pixel
  // Refinement stops sooner once the refined image's estimated relative
  // error (pipeline/refine.h) is at most this; 0: only at target_spp.
  float error_target = kDefaultErrorTarget;
  // Interactive resolution, a frame-time budget in milliseconds: the time
  // from one of this pipeline's frames to the next while it renders back to
  // back, waiting for the GPU and for a worker included. While the camera or
  // the transfer function moves, frames step down through 0.75 and 0.5 of the
  // viewport's width and height while they come slower than the budget, and
  // back up when the larger size would meet it with room to spare; they are
  // upsampled on the device, and the next interaction starts at the scale the
  // last one ended with. Once the view holds still for kInteractionHoldMs,
  // frames refine at full size. 0: always full size, the default, since a
  // smaller frame costs accuracy (docs/tradeoff.md: -1.1 dB at 0.75, -2.8 dB
  // at 0.5, on CThead at 720p).
  //
  // On the CPU backend (InteractivePolicy::kCostModel) a budget also means a
  // live view: frames follow every edit that changes the picture (lights,
  // clipping and labels too), choose their size down to an eighth of the
  // viewport and their samples per pixel (up to the scene's) from the
  // measured cost of each part, take more samples per frame when still
  // (frame_cost.h), and a still frame stops when a newer event preempts it
  // (SetPreempt).
  float interactive_frame_ms = 0;
  // true: a frame rendered smaller leaves at that size (DisplayFrame::width
  // says the viewport it is shown at) for the client to stretch: the display
  // and encode pay for the rendered pixels only. false: upsampled here.
  bool frames_at_rendered_size = false;
  // false: every frame shows the denoiser's output alone, never the
  // accumulation (the benches measure frames as they look while interacting).
  bool refine = true;
  // Each YCbCr sample keeps the code it showed last frame while its exact
  // value stays within a code of it (core/ycc.h, HeldCode): a still view's
  // noise no longer flips codes at rounding steps. A final frame shows its
  // exact codes. false: every frame rounds plainly (the benches' comparison).
  bool hold_codes = true;
};

// A streamed session's settings on `backend`: the defaults (on the CPU,
// interactive_frame_ms = kCpuInteractiveFrameMs) with the fields `stream`
// sets (checked: scene/session_state.h's CheckStreamSettings).
FrameSettings SessionFrameSettings(Backend backend, const v1::StreamSettings& stream = {});
// Every field of `settings` the stream settings hold, set: what a session's
// state says it streams with.
v1::StreamSettings ToStreamSettings(const FrameSettings& settings);

// The resolution scales interactive frames step through, largest first; how
// long after the last camera or transfer-function change they end; and how
// many frame times a scale is measured over before the next step (a step
// restarts the denoiser's history, so steps are rare). 0.375 is for a crowded
// GPU: 128 sessions on an H200 make 25-26 fps each at 0.5 and 34-36 at 0.375
// (docs/performance.md; its cost while moving, -5 dB: docs/tradeoff.md).
inline constexpr float kInteractiveScales[] = {1.0f, 0.75f, 0.5f, 0.375f};
inline constexpr int kInteractionHoldMs = 200;
inline constexpr int kFrameTimesPerStep = 3;

// How interactive frames choose their size.
enum class InteractivePolicy {
  // The GPU's: the scene's spp, and the size steps through
  // kInteractiveScales, one step after kFrameTimesPerStep frame times over
  // (or well under) the budget.
  kSteps,
  // The CPU's: size and spp from a model of each part's cost (frame_cost.h),
  // more samples per still frame, still frames preemptible.
  kCostModel,
};

// A frame ready to encode, with what it cost. The planes are at the
// settings' chroma subsampling; ToRgb (core/ycc.h) gives the pixels back.
struct DisplayFrame {
  ImageYcc8 image;             // empty where final_rgb or jpeg holds the frame
  ImageRgb8 final_rgb;         // the final frame, where FrameSettings::final_png asks for its exact pixels
  EncodedJpeg jpeg;            // the frame encoded on the GPU, where SetJpegEncoder asks for nvJPEG
  int jpeg_quality = 0;        // the settings' quality for this frame (final or not): jpeg's, or the one to encode at
  int accumulated_spp = 0;     // samples per pixel behind it since the scene last changed
  bool final = false;          // refinement reached its error target or target_spp with this frame
  float estimated_error = -1;  // refined frames: the image's estimated relative error; < 0 unknown
  float resolution_scale = 1;  // < 1: rendered at this fraction of the viewport's width and height
  int width = 0, height = 0;   // the viewport: the size to show the frame at, whatever the image's
  int spp = 0;                 // samples per pixel this frame rendered
  // A newer event stopped the frame (SetPreempt): no image; the
  // accumulation restarted.
  bool preempted = false;
  double render_ms = 0, denoise_ms = 0, display_ms = 0;  // display_ms: upsampling, refinement and display
  double encode_ms = 0;  // the GPU's encode of jpeg (after display_ms); 0 where the caller encodes
};

class FramePipeline {
 public:
  // `labels`: the volume's segmentation, where it has one (Scene.labels styles it).
  FramePipeline(Backend backend, std::shared_ptr<const Volume> volume, const RendererOptions& options = {},
                std::shared_ptr<const LabelVolume> labels = nullptr);
  ~FramePipeline();

  // Takes the scene (validated, defaults filled) and settings; rebuilds only
  // what `changes` (SceneChange bits) says changed since the previous call,
  // and whatever the settings change; the first call takes everything.
  // Throws InputError for a scene the volume cannot resolve (e.g. an
  // unreadable environment map).
  void Update(const v1::Scene& scene, const FrameSettings& settings, unsigned changes = kEverythingChanged);
  // The same from a scene already resolved against the volume: the benches'
  // scenarios move cameras, lights and transfer functions no scene file
  // names. Reads only the parts `changes` names (and the sampling and
  // exposure, every time).
  void Update(const RenderSetup& setup, const FrameSettings& settings, unsigned changes = kEverythingChanged);
  // Shows another phase of the volume's time series (alike in grid: the
  // segmentation still fits), the scene kept: its tables and majorants are
  // rebuilt for the phase's values, the accumulation restarts, and the
  // denoiser's history goes as FrameSettings::phase_history says.
  void SetPhase(std::shared_ptr<const Volume> phase);
  // The second volume a scene's fusion names (Scene.fusion; null: none),
  // before the Update that shows it: scenes name it by id.
  void SetFusedVolume(std::shared_ptr<const Volume> fused) { fused_ = std::move(fused); }

  // One frame of the scene's spp: render, denoise, refine, tone map.
  DisplayFrame RenderFrame();
  // Adds `spp` samples to the accumulation only (stills, offline renders):
  // not for a pipeline whose frames refine, whose error estimate counts frames.
  void Accumulate(int spp);
  // Frames check `cancel` as they render (FrameRequest::cancel); a cancelled
  // frame throws Cancelled and leaves the pipeline to be discarded.
  void SetCancel(const std::atomic<bool>* cancel) { cancel_ = cancel; }
  // Under InteractivePolicy::kCostModel with a budget, a still frame stops
  // when `preempt` is raised and RenderFrame returns a preempted frame
  // (no image): the caller raises it when an event that changes the picture
  // arrives, and lowers it before the next frame.
  void SetPreempt(const std::atomic<bool>* preempt) { preempt_ = preempt; }
  // The backend's by default (kSteps on a GPU, kCostModel on the CPU); tests
  // pick the other to check it on the CPU.
  void SetInteractivePolicy(InteractivePolicy policy) { policy_ = policy; }
  // kAutoFeatures (the default) renders with the smallest specialised
  // integrator; `cinevol-bench render` forces kAllFeatures to measure what
  // specialisation buys.
  void SetRenderFeatures(unsigned features) { render_features_ = features; }
  // kCpu (the default): frames leave the device as planes (DisplayFrame::image)
  // for the caller to encode. kCuda, kNvjpeg: frames that would leave as
  // planes are encoded on the GPU instead (DisplayFrame::jpeg; the planes
  // still, where the encoder gives a frame back); takes ChooseJpegEncoder's
  // choice. Throws InputError where that encoder cannot encode this
  // pipeline's frames; call on the pipeline's thread.
  void SetJpegEncoder(JpegEncoderKind kind);

  int accumulated_spp() const { return accumulated_spp_; }
  // Bumped by every transfer-function or light rebuild.
  std::uint64_t scene_version() const { return scene_version_; }
  // Refinement is done: a full-size image at the error target, or with
  // target_spp samples behind it.
  bool Converged() const;
  ImageRgbF AccumulatedRadiance() const { return renderer_->AccumulatedMean(); }
  // The last frame's nearest first real collision per pixel (Renderer::FirstHits),
  // of a CPU pipeline: on a GPU they were the frame's scratch, which any
  // later frame there may have taken.
  std::vector<Vec4f> FirstHits() const { return renderer_->FirstHits(); }
  // The last frame's denoised linear radiance, before refinement and tone
  // mapping (the benches compare it with references in HDR).
  ImageRgbF DenoisedRadiance() const { return denoiser_->Output(); }
  // The last refined frame's radiance before the display; empty where the
  // frame was not blended (refinement off, fewer than kMinFramesForError frames).
  ImageRgbF RefinedRadiance() const;
  float exposure() const { return exposure_; }
  Backend backend() const { return renderer_->backend(); }
  unsigned last_render_features() const { return renderer_->last_features(); }
  // What edits cost: transfer functions resolved and majorant grids built
  // since construction. A camera move builds neither.
  std::uint64_t transfer_function_builds() const { return transfer_function_builds_; }
  std::uint64_t majorant_builds() const { return renderer_->majorant_builds(); }

 private:
  void SetTransferFunction(TransferFunction tf);
  void SetLabels(const LabelSetup& setup);  // styles the segmentation, if any, and keeps its framing blocks
  // What every update ends with: the denoiser, its cue and the accumulation.
  void Apply(const FrameSettings& settings, unsigned changes);
  FrameRequest Request(int spp);
  // On a GPU, the frame's scratch from the GPU's pool until it goes out of
  // scope: once the frame's work is queued (device/frame_scratch.h).
  std::optional<FrameScratchScope> GpuFrameScratch(const Camera& camera) const;
  bool Moving() const;
  bool LiveOnCpu() const { return policy_ == InteractivePolicy::kCostModel && settings_.interactive_frame_ms > 0; }
  float ChooseScale();
  // kCostModel: the next frame's size (SetScale) and samples per pixel.
  int ChooseCostModelFrame(bool moving);
  void SetScale(float scale);
  void ResetAccumulation();
  // Takes the time since the previous frame started, when it rendered back
  // to back with this one.
  void MeasureFrameTime(std::chrono::steady_clock::time_point start);

  std::shared_ptr<const Volume> volume_;
  std::shared_ptr<const LabelVolume> labels_;
  std::shared_ptr<const Volume> fused_;  // Scene.fusion's volume, where the scene may fuse one
  LabelSetup label_setup_;               // the segmentation's styles, set again on a phase switch
  std::unique_ptr<Renderer> renderer_;
  std::unique_ptr<Denoiser> denoiser_;
  std::unique_ptr<Display> display_;
  std::unique_ptr<Upsampler> upsampler_;
  std::unique_ptr<Refiner> refiner_;
  std::unique_ptr<DeviceJpegEncoder> device_jpeg_;  // null: frames leave as planes
  bool last_frame_blended_ = false;                 // the last frame showed refiner_'s blend
  ClipRegion clip_;                                 // the scene's, resolved: named views frame what it keeps
  FrameSettings settings_;
  bool has_scene_ = false;
  TransferFunction transfer_function_;
  Camera camera_;
  int spp_ = 1, max_bounces_ = 0;
  std::uint64_t seed_ = 0;
  float exposure_ = 0;
  unsigned render_features_ = kAutoFeatures;
  std::uint64_t transfer_function_builds_ = 0;
  std::uint64_t scene_version_ = 0;  // bumped on edits of the picture other than the camera's (tests read it)
  bool picture_changed_ = true;      // since the denoiser's last frame (DenoiseFrame::changed)
  bool shading_changed_ = true;      // the same, other than by the camera (DenoiseFrame::only_moved)
  std::uint32_t frame_ = 0;          // seeds each frame's samples
  int accumulated_spp_ = 0;
  float estimated_error_ = -1;  // the last refined frame's estimate; < 0 none yet
  // Interactive resolution: the scale this frame renders at, the scale moving
  // views render at (kept from one interaction to the next), when the view
  // last moved, and the frame time measured at scale_ (a running mean of
  // frame_times_ - 1 frames: the first at a new size pays its allocations).
  float scale_ = 1;
  float moving_scale_ = 1;
  std::chrono::steady_clock::time_point moved_at_{};
  double frame_ms_ = 0;
  int frame_times_ = 0;
  std::chrono::steady_clock::time_point last_frame_start_{};
  bool last_frame_final_ = true;  // then the next frame waited for an event: no frame time
  // kCostModel: what each part costs, the samples moving frames take, and the
  // samples of the last still frame (0: none since the scene changed).
  InteractivePolicy policy_;
  FrameCostModel cost_;
  int moving_spp_ = 1;
  int still_spp_ = 0;
  const std::atomic<bool>* cancel_ = nullptr;
  const std::atomic<bool>* preempt_ = nullptr;
};

}  // namespace cinevol
