// Real-time denoisers for the path tracer's frames, behind one interface:
// the wRLS denoiser of Iglesias-Guitian et al. and the baselines it must beat
// (accumulation, Exposure Render's KNN filter, a guided image filter, SVGF).
// Each runs on the CPU and on CUDA from one source; a denoiser reads frames
// in the memory of the renderer of the same backend.
//
// Lifecycle: CreateDenoiser(settings), then Denoise(frame) per frame. The
// settings are fixed for a denoiser's life: a change makes a new denoiser,
// and with it a new history (FramePipeline does so). History lives across
// frames, reprojected: a cut needs no call, since only history whose first
// hits project back is used; a new frame size resets it.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "core/camera.h"
#include "core/image.h"
#include "core/vec.h"
#include "device/device.h"

namespace cinevol {

enum class DenoiseMethod { kNone, kAccumulate, kKnn, kGuidedFilter, kSvgf, kWrls };

// "none", "accumulate", "knn", "guided", "svgf", "wrls"; throws InputError otherwise.
DenoiseMethod ParseDenoiseMethod(std::string_view name);
const char* ToString(DenoiseMethod method);

// The largest normal stop a setting may take: a pixel's own tap differs from
// itself only by rounding (|a| |a| against a . a), which a larger stop could
// turn into a weight of 0 and an a-trous level into 0 / 0.
inline constexpr float kMaxNormalStop = 1000.0f;

// Weighted recursive least squares (Iglesias-Guitian et al., Sec. 5-6). Every
// model is per pixel and channel, predictor p = [1, z] over the temporal
// feature z; models and features are reprojected from the previous frame.
// Defaults are the study's best at 1280x720, 2 spp (docs/tradeoff.md). Only
// the knobs the study still turns are here; the stages it settled run
// always (each pixel's own prediction, not the paper's 5x5 blend: +2.0 dB on
// the CThead orbit; adaptive forgetting, recentering and the feature's
// rescaling: docs/denoising.md keeps what each was measured at).
struct WrlsSettings {
  float alpha = 0.75f;  // [0, 1): weight of the reprojected history in the feature z (Eq. 12); 0.8, 0.85 cost CThead's
                        // lights 0.6-0.7 dB
  float bandwidth = 0.75f;  // h > 0: sample weight exp(-d^2 / h^2) (Eq. 13, wrls.h SampleWeight); smaller is steadier
  float lambda = 0.998f;    // (0, 1]: forgetting factor; 1 never forgets
  // > 0: a reset model's inverse covariance, diagonal, in normalised units.
  // A firm prior (0.1, not 1: +0.4-1.0 dB on orbits, edits and still views)
  // holds still radiance; drift_sigma lets a change through.
  float initial_p = 0.1f;
  float max_trace_p = 1e3f; // > initial_p: trace(P) is scaled back to this (covariance wind-up)
  float max_coefficient = 1e4f;  // a model with |beta| beyond this resets
  float firefly_clamp =
      4.0f;  // >= 1: the sample entering z is clamped to this times the local level (neighbours' mean, history)
  // A view that stays still accumulates: the feature's history weight grows
  // as 1 - 1/n over the still frames, up to this many (1: never; alpha always).
  int max_still_frames = 1024;
  float residual_rate = 0.1f;    // (0, 1]: how fast the model's residual variance follows new frames
  // > 0: adaptive forgetting (wrls.h, AdaptForgetting): when the running
  // mean of the residual drifts beyond this many deviations of the noise, P
  // widens. 2 gains 0.4-0.5 dB under moving point lights; 3 reads the same.
  float drift_sigma = 2.0f;
  // A young model's predicted variance is at least young_variance /
  // samples^2 times its noise (wrls.h, PredictionVariance): with the firm
  // prior, 4 takes 3-4% off the MR head's temporal error and 8 1% more;
  // 16 takes 1.5% more for 0.2 dB.
  float young_variance = 8.0f;   // >= 0
  // >= 0: the floor instead where the pixel's 5x5 window all hit the volume
  // (its coverage is 1: a surface, not semi-transparent tissue, whose thin
  // shells need the floor's smoothing); < 0: young_variance everywhere. On
  // the study's 28 runs at 720p (an H100), 4 gains up to 0.20 dB and loses
  // at most 0.02 (2 loses 0.08 on the phantom's shells), but raises temporal
  // error on most runs and takes two more over SVGF's: off (docs/tradeoff.md,
  // "What is still short of the goal").
  float young_variance_surface = -1.0f;
  // [1, 8]: before the blend, the feature's reprojected history is scaled by
  // the ratio of this frame's input to it over (2r + 1)^2 taps 2 pixels apart
  // (wrls.h, Rescaled), so the feature does not lag a light that moves
  // (+1.0 to +5.4 dB under the moving point lights at 720p; 3 reads within
  // 0.2 dB of 5, 8 is the next candidate).
  int feature_rescale = 5;
  float feature_rescale_sigma = 3.0f;  // >= 0: the scaling is shrunk where it is within this many deviations of noise
  // A-trous levels on the predictions (steps 1, 2, 4, 8), stopped at
  // coverage, depth and luminance edges (the last scaled by the deviation the
  // RLS fit predicts). 4 against 5 at 720p: +0.03 to +0.57 dB on all 28 runs
  // of the study, temporal error and flicker the same, 9% less time; 3 gains
  // more on most runs but blurs the semi-transparent shells (SSIM, temporal
  // error) and loses 0.05 dB under the MR head's area light
  // (docs/tradeoff.md, "Four a-trous levels").
  int atrous_iterations = 4;     // [0, 5]
  float atrous_sigma_luminance = 4.0f;  // 3 trades 0.9-2.4% temporal error for 0.1-0.3 dB, 5 the other way
  // The luminance stop squared (AtrousPass::squared_luminance). At 720p with
  // sigma 3: +0.4 to +0.8 dB on the aorta crop, up to +0.4 on CThead and the
  // phantom, -0.1 to -0.5 on the MR head (sigma 4: +0.3 and -0.1; 5-6: the
  // aorta crop loses): not taken (docs/tradeoff.md, "A squared luminance stop").
  bool atrous_squared_luminance = false;
  // > 0: the variance the luminance stop reads is scaled, once a frame, by
  // how far it is from the spread it predicts (StopCalibrationPass,
  // baselines.h), no lower than this; 0: not scaled. With the squared stop at
  // sigma 6.5, a floor of 1/16 and a fall of 0.9, +0.24 dB on average over the
  // study's 28 runs at 720p (-0.05 at worst, +0.95 on the aorta crop), for up
  // to 5% more temporal error and 3% of the time (a floor of 1/4: -0.02 at
  // worst, +0.20 on average, up to 3.4%): off (docs/tradeoff.md, "A
  // calibrated luminance stop").
  float atrous_calibration_floor = 0.0f;
  // [0, 1]: a frame's scale is no lower than this times the previous one's
  // (a moving light's lag inflates the predicted variance, and the scale
  // would tighten the stop where it should stay loose).
  float atrous_calibration_fall = 0.0f;
  // Relative depth tolerance (times 1% of the distance and the step). Loose:
  // the first hit in semi-transparent tissue is itself a noisy estimate
  // (8 against 1: +1.2 dB on the CThead orbit).
  float atrous_sigma_depth = 8.0f;
  // (0, kMaxNormalStop]: the levels also stop between surfaces that face
  // different ways (AtrousPass::normals, normal_stop; the renderer then
  // writes FrameTargets::surface_normal); 0: no normal stop.
  float atrous_normal_stop = 0.0f;
  // (0, 1]: the normal stop reads this frame's normals blended into the
  // previous frame's guide with this share (NormalGuidePass); 1: this frame's.
  float atrous_normal_share = 1.0f;
  // Temporal stabilisation of the output (as NRD's): the previous output,
  // reprojected, recentred and clipped to where this frame's estimate could
  // lie (+- stabilize_clamp deviations), is blended in with this weight
  // (0: the estimate alone). It steadies what the a-trous levels leave from
  // frame to frame (0.3, 0.6 and 0.7 balance no better); the regression
  // never sees it.
  float stabilize_history = 0.5f;  // [0, 1)
  float stabilize_clamp =
      4.0f;  // >= 0: width of the clip box in deviations (wide: recentering takes the lag; 4 and 100 read the same)
  // [1, 8]: the history is first shifted by its mean offset from the
  // estimate over (2r + 1)^2 taps 2 pixels apart, so a shading change does
  // not lag (wrls.h, HistoryOffsetTap; 3 reads as 5).
  int stabilize_recenter = 5;
  // Recentre also a pixel that stayed where it was while only the camera
  // moved (DenoiseFrame::only_moved): its history is exact and the lights
  // and what is drawn held still, so its shift from the estimate is noise
  // that recentering would pass on (the centre of a zoom, the axis of a
  // turn; most of all the study's still view, which says every frame that
  // the camera moved: the server takes an unchanged camera as no change).
  // Measured in docs/tradeoff.md, "Recentering only where something moved".
  bool stabilize_recenter_unmoved = false;
  // On a still view the output accumulates as the feature does: the history
  // weight grows as 1 - 1/(n + 1) over the n still frames, up to this many,
  // and is not recentred (nothing moved; recentering would pass on the
  // estimate's frame-to-frame change). It halves the still view's flicker
  // before rounding, and costs a fresh still view's first frames up to
  // 1.15 dB on the aorta crop, gains up to 0.8 on shells (docs/tradeoff.md,
  // "Flicker on the display"); 0: the moving view's rule always.
  int stabilize_still_frames = 32;
  friend bool operator==(const WrlsSettings&, const WrlsSettings&);  // defaulted in denoiser.cpp
};

// Exposure Render's KNN (non-local means style) filter over the accumulated
// image, fading out as samples accumulate.
struct KnnSettings {
  int radius = 3;              // 7x7 window
  float strength =
      4.0f;  // h: colour distance (relative to the pixel's luminance) where weights fall off; 1, 2, 4 measured, 4 best
  float fade_frames = 32.0f;   // frames over which the filter fades to the plain accumulation
  friend bool operator==(const KnnSettings&, const KnnSettings&);  // defaulted in denoiser.cpp
};

// He et al.'s guided filter with a two-channel guide from what the volume
// offers: the temporal feature's luminance and the first-collision depth.
struct GuidedFilterSettings {
  int radius = 8;                 // box window (2r+1)^2
  float epsilon_feature = 0.01f;  // regulariser on the (relative) feature guide
  float epsilon_depth = 0.01f;    // regulariser on the (normalised) depth guide
  float alpha = 0.75f;            // temporal feature blend, as in wRLS
  friend bool operator==(const GuidedFilterSettings&, const GuidedFilterSettings&);  // defaulted in denoiser.cpp
};

// Schied et al. 2017 with our reprojection: temporal accumulation of colour
// and moments, variance-guided a-trous wavelet filtering (depth and luminance
// edge stops; volumes have no reliable normals).
struct SvgfSettings {
  float color_alpha = 0.2f;    // history blend for colour
  float moments_alpha = 0.2f;  // history blend for the moments
  int iterations = 5;          // a-trous levels (step 1, 2, 4, 8, 16)
  float sigma_luminance = 4.0f;
  float sigma_depth = 1.0f;
  bool squared_luminance = false;  // AtrousPass::squared_luminance; the paper's stop is not squared
  // AtrousPass::normal_stop (the paper's normals: its G-buffer's), up to
  // kMaxNormalStop; 0: none.
  float normal_stop = 0.0f;
  friend bool operator==(const SvgfSettings&, const SvgfSettings&);  // defaulted in denoiser.cpp
};

struct DenoiserSettings {
  DenoiseMethod method = DenoiseMethod::kWrls;
  // Divide by the first-hit albedo before denoising and multiply after
  // (an option around any method, so its value can be measured).
  bool demodulate = false;
  WrlsSettings wrls;
  KnnSettings knn;
  GuidedFilterSettings guided;
  SvgfSettings svgf;
  // A pipeline makes a new denoiser when its settings change. The
  // comparisons are defaulted in denoiser.cpp, not here: CUDA code builds as
  // C++17, which has no defaulted comparisons.
  friend bool operator==(const DenoiserSettings&, const DenoiserSettings&);
};

// One frame from the renderer, in the denoiser's backend memory.
struct DenoiseFrame {
  int width = 0, height = 0;
  const Vec3f* radiance = nullptr;   // noisy linear HDR
  const Vec4f* first_hit = nullptr;  // nearest first real collision (w = 1) or escaped (w = 0)
  const Vec3f* albedo = nullptr;     // first-hit diffuse colour; needed when demodulating
  Camera camera;                     // the camera that rendered it
  // The picture changed since the previous frame this denoiser got: the
  // camera, transfer function, lights, clipping or labels (the pipeline's
  // change bits say so; nothing compares cameras). false: only the samples did.
  bool changed = true;
  // The change was the camera's alone: what is drawn, and the lights, held
  // still in the patient's frame, so a surface point's shading moved only as
  // far as it depends on the view. false where unknown.
  bool only_moved = false;
  // FrameTargets::surface_normal, where the settings stop at normals
  // (UsesSurfaceNormals); null otherwise.
  const Vec3f* surface_normal = nullptr;
};

// The settings stop the a-trous levels at surface normals: the renderer
// must write FrameTargets::surface_normal.
bool UsesSurfaceNormals(const DenoiserSettings& settings);

class Denoiser {
 public:
  virtual ~Denoiser() = default;
  // Denoises one frame; returns the result in the backend's memory, valid
  // until the next call.
  virtual const Vec3f* Denoise(const DenoiseFrame& frame) = 0;
  // The last result, on the host.
  virtual ImageRgbF Output() const = 0;
  // Time the last Denoise took: wall time on the CPU, CUDA events on the GPU.
  virtual double LastMilliseconds() const = 0;
};

// kAuto: CUDA where a usable GPU is present. Throws InputError for kCuda
// without one.
std::unique_ptr<Denoiser> CreateDenoiser(Backend backend, const DenoiserSettings& settings);

}  // namespace cinevol
