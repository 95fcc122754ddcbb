// The speed/accuracy study behind `cinevol-bench tradeoff` (docs/tradeoff.md):
// the wRLS paper's interaction scenarios (Sec. 7) on real volumes, every
// frame rendered at a low sample count, denoised, displayed (and JPEG coded)
// as a viewer sees it, and compared with a high-spp reference of the same
// frame, cached on disk. Each knob that buys speed (denoiser, samples per
// pixel, bounces, JPEG quality, resolution) is swept around a baseline.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/image.h"
#include "denoise/denoiser.h"
#include "pipeline/frame_pipeline.h"
#include "scene/scene_builder.h"

namespace cinevol::bench {

struct Dataset {
  std::string name;    // "ct-head-cthead"
  std::string scene;   // scene file
  std::string volume;  // overrides the scene's volume when set
};

// One point of the study: a denoiser and the knobs around it.
struct StudyConfig {
  std::string knob = "denoiser";  // the sweep it belongs to: denoiser, spp, bounces, jpeg, scale
  DenoiseMethod method = DenoiseMethod::kWrls;
  bool demodulate = false;
  int spp = 2;                                        // samples per pixel per frame
  int bounces = 4;                                    // scattering events per path
  int jpeg_quality = 0;                               // 0: the display image as rendered (no JPEG)
  float scale = 1;                                    // resolution scale: rendered smaller, upsampled for display
  bool hold_codes = true;                             // FrameSettings::hold_codes
  PhaseHistory phase_history = PhaseHistory::kReset;  // a time series' phase switch (the beat scenario)
  std::string variant;                                // a named variant (ablations); empty: the defaults
  WrlsSettings wrls;
  SvgfSettings svgf;
  std::string Label() const;
};

// "NAME:key=value,..." -> a wRLS configuration with those settings changed.
// Keys: alpha, bandwidth, lambda, initial_p, atrous, sigma_luminance,
// sigma_depth, still, residual_rate, drift, young, firefly, stabilize,
// stabilize_clamp, recenter, stabilize_still, rescale, rescale_sigma
// (WrlsSettings);
// method=svgf makes it an SVGF variant (keys sigma_luminance, sigma_depth).
// Either method also takes spp (samples per pixel per frame), hold (0:
// the display rounds every frame plainly, FrameSettings::hold_codes) and
// phase_history (changed, reset or kept: FrameSettings::phase_history).
StudyConfig Variant(const std::string& spec);

// The baseline and one-at-a-time sweeps of every knob; `quick` a small subset.
std::vector<StudyConfig> StudyConfigs(bool quick);

struct StudyOptions {
  std::vector<Dataset> datasets;
  std::vector<std::string> scenarios;  // empty: all (ScenarioNames())
  std::vector<StudyConfig> configs;
  int width = 1280, height = 720;
  float frames_scale = 1;  // scenario lengths times this (CI: small)
  int reference_spp = 1024;
  // The bounces sweep's references: long paths, the truth the sweep is
  // measured against. Every other configuration is compared with the
  // converged image of what it renders (references at its own bounces): a
  // denoiser's error, not the bias of shorter paths, which a denoiser that
  // leans bright would partly cancel (docs/tradeoff.md).
  int reference_bounces = 8;
  std::filesystem::path cache = "bench-cache";  // references, as EXR
  std::filesystem::path out;                    // tradeoff.csv, tradeoff.json, images/ (none when empty)
  std::string backend = "auto";
  std::string command_line;
};

struct FrameResult {
  int frame = 0;
  double psnr = 0, ssim = 0, rel_mse = 0;
  // PSNR against the converged image, the reference's own noise taken out
  // (CorrectedPsnr): where a denoiser's error is near that noise, plain PSNR
  // reads two denoisers closer than they are.
  double psnr_corrected = 0;
  double temporal = 0;  // 0 on the first frame
  double render_ms = 0, denoise_ms = 0, tonemap_ms = 0, encode_ms = 0;
};

struct RunResult {
  std::string dataset, scenario;
  StudyConfig config;
  std::vector<FrameResult> frames;
  // RMS change between displayed frames of the first frame's view held
  // still, and between their display values before 8-bit rounding; the
  // same frames' PSNR against the first frame's reference.
  double flicker = 0, flicker_unrounded = 0, still_psnr = 0;
  // Means over frames; temporal over frames 1.. ; times over all frames.
  double Mean(double FrameResult::*field) const;
  double MeanMs() const;  // render + denoise + tone map + encode
};

std::vector<std::string> ScenarioNames();

// Runs the whole study; writes results when options.out is set.
std::vector<RunResult> RunStudy(const StudyOptions& options);

// What the benchmarks share: the camera turned about its up axis through the
// point it looks at, and a reference image of one view (its camera,
// transfer function and lights): `spp` samples at `bounces` in chunks of 64,
// in two halves with seeds of their own (what tells the reference's noise,
// ReferenceNoise), each accumulated by a FramePipeline of its own. Every
// view's chunks have the same seeds, so two views' references differ by what
// changed between them, not by their noise: a still view's references are
// one image.
Camera Orbit(const Camera& camera, float degrees);
struct ReferenceHalves {
  ImageRgbF a, b;  // b is empty at 1 sample
  int a_spp = 0, b_spp = 0;
  static ReferenceHalves Split(int spp);  // no images yet: how many samples each half takes
  ImageRgbF Mean() const;                 // by samples: the reference
};
ReferenceHalves RenderReferenceHalves(Backend backend, std::shared_ptr<const Volume> volume, RenderSetup view, int spp,
                                      int bounces);
ImageRgbF RenderReference(Backend backend, std::shared_ptr<const Volume> volume, RenderSetup view, int spp,
                          int bounces);

// Markdown: per scenario, every configuration's means.
std::string SummaryTable(const std::vector<RunResult>& results);

}  // namespace cinevol::bench
