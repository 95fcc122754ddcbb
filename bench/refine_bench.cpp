// `cinevol-bench refine`: still frames as a viewer sees them after a short
// orbit stops. Every displayed frame of the still camera is compared with a
// high-spp render of the same view (PSNR and SSIM of the displayed 8-bit
// image, 4:4:4, before JPEG), for the refinement the pipeline does now (per
// pixel, by estimated error: pipeline/refine.h) beside the previous
// release's global blend (the denoiser's output alone up to 16 spp, then
// towards the mean with log(spp), the mean alone at target_spp) and beside
// the raw mean of the samples (what `cinevol render` wrote before it
// refined), on the same samples.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "bench.h"
#include "image_metrics.h"
#include "core/error.h"
#include "core/ycc.h"
#include "encode/hdr_images.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/refine.h"
#include "tradeoff_study.h"

namespace cinevol::bench {
namespace {

// The previous release's refinement (pipeline before issue 21), kept here
// only as the baseline the new one is measured against.
float PreviousBlend(int spp, int target_spp) {
  constexpr int kStart = 16;
  if (spp >= target_spp) return 1.0f;
  if (spp <= kStart) return 0.0f;
  return std::log(float(spp) / kStart) / std::log(float(target_spp) / kStart);
}

ImageRgbF Lerp(const ImageRgbF& a, const ImageRgbF& b, float t) {
  ImageRgbF out = a;
  for (std::size_t i = 0; i < out.pixels.size(); ++i) out.pixels[i] = a.pixels[i] * (1.0f - t) + b.pixels[i] * t;
  return out;
}

struct Curve {
  std::vector<double> psnr, ssim, ms;  // per still frame; ms: wall clock since the camera stopped
};

// The first step at which PSNR reaches `db`, or -1.
int FirstAt(const Curve& c, double db) {
  for (std::size_t i = 0; i < c.psnr.size(); ++i) {
    if (c.psnr[i] >= db) return int(i);
  }
  return -1;
}

double LargestDrop(const Curve& c) {
  double drop = 0;
  for (std::size_t i = 1; i < c.psnr.size(); ++i) drop = std::max(drop, c.psnr[i - 1] - c.psnr[i]);
  return drop;
}

}  // namespace

int RunRefineBench(const RefineBenchOptions& o) {
  LoadedScene loaded = LoadScene(o);
  if (o.seed >= 0) loaded.setup.seed = std::uint64_t(o.seed);
  const RenderSetup& setup = loaded.setup;
  const Backend backend = Resolve(ParseBackend(o.backend), "refine bench");
  using Clock = std::chrono::steady_clock;

  // The reference does not depend on the frames' seed (RenderReference seeds its own chunks).
  ImageRgbF reference;
  if (!o.reference.empty() && std::filesystem::exists(o.reference)) {
    reference = ReadExr(o.reference);
    if (reference.width != setup.camera.width || reference.height != setup.camera.height)
      throw InputError(
          fmt::format("--reference {}: {}x{}, not the frames' size", o.reference, reference.width, reference.height));
  } else {
    reference = RenderReference(backend, loaded.volume, setup, o.reference_spp, setup.max_bounces);
    if (!o.reference.empty()) WriteExr(o.reference, reference);
  }
  const ImageRgb8 reference_shown = ShownOnCpu(reference, setup.exposure);

  // Two pipelines on the same samples: `previous` with refinement off
  // shows the denoiser's output, blended here with its mean as the previous
  // release did; `now` refines as sessions do.
  FrameSettings off, on;
  if (!o.variant.empty()) {
    const StudyConfig c = Variant(o.variant);
    for (FrameSettings* s : {&off, &on}) {
      s->denoiser.method = c.method;
      s->denoiser.wrls = c.wrls;
      s->denoiser.svgf = c.svgf;
      s->hold_codes = c.hold_codes;
    }
  }
  off.refine = false;
  on.target_spp = off.target_spp = o.target_spp;
  on.error_target = 0;  // the whole curve; where the error target stops it is read off the estimates
  on.chroma = ChromaSubsampling::k444;
  FramePipeline previous(backend, loaded.volume), now(backend, loaded.volume);
  for (int t = o.orbit_frames; t >= 0; --t) {  // the orbit ends at the scene's view
    RenderSetup view = setup;
    view.camera = Orbit(setup.camera, 2.0f * float(t));
    previous.Update(view, off, kCameraChanged);
    now.Update(view, on, kCameraChanged);
    if (t > 0) {
      previous.RenderFrame();
      now.RenderFrame();
    }
  }

  Curve before, after, raw;
  std::vector<int> spp;
  std::vector<float> estimate;
  std::vector<double> measured;  // the refined image's relative error against the reference
  const float dark = kDarkGrey / exp2f(setup.exposure);
  double before_ms = 0, after_ms = 0;
  RenderSetup still = setup;  // the view the orbit ended at
  still.camera = Orbit(setup.camera, 0.0f);
  while (spp.empty() || spp.back() < o.target_spp) {
    if (o.still_ramp > 0) {  // a CPU session's still frames: the scene's spp, then doubling, within the target
      const int done = spp.empty() ? 0 : spp.back();
      still.spp = std::min(spp.empty() ? setup.spp : std::min(2 * still.spp, std::max(o.still_ramp, setup.spp)),
                           o.target_spp - done);
      previous.Update(still, off, 0u);
      now.Update(still, on, 0u);
    }
    // The previous release blended on the device in its display pass, at no
    // measurable cost: its time is the frame's, not this host-side blend's.
    Clock::time_point start = Clock::now();
    const DisplayFrame a = previous.RenderFrame();
    before_ms += std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    const ImageRgbF shown_before = Lerp(previous.DenoisedRadiance(), previous.AccumulatedRadiance(),
                                        PreviousBlend(a.accumulated_spp, o.target_spp));
    start = Clock::now();
    const DisplayFrame b = now.RenderFrame();
    after_ms += std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    const ImageRgb8 x = ShownOnCpu(shown_before, setup.exposure), y = ToRgb(b.image);
    const ImageRgb8 mean = ShownOnCpu(now.AccumulatedRadiance(), setup.exposure);
    raw.psnr.push_back(Psnr(mean, reference_shown));
    before.psnr.push_back(Psnr(x, reference_shown));
    before.ssim.push_back(Ssim(x, reference_shown));
    before.ms.push_back(before_ms);
    after.psnr.push_back(Psnr(y, reference_shown));
    after.ssim.push_back(Ssim(y, reference_shown));
    after.ms.push_back(after_ms);
    spp.push_back(b.accumulated_spp);
    estimate.push_back(b.estimated_error);
    const ImageRgbF refined = now.RefinedRadiance();
    measured.push_back(RelativeRmsError(refined.pixels.empty() ? now.DenoisedRadiance() : refined, reference, dark));
  }

  std::string table = fmt::format(
      "\n### Still frames on {} ({})\n\n`{}`\n\n{}x{}, {} spp a frame, {} orbit frames then a still camera; "
      "PSNR and SSIM of the displayed image (8-bit, 4:4:4, before JPEG) against {} spp; ms: wall clock since "
      "the camera stopped; estimate: the refined image's estimated relative error\n\n"
      "| spp | raw mean PSNR | previous PSNR | SSIM | ms | refined PSNR | SSIM | ms | estimate | measured |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n",
      o.scene, DeviceDescription(o.backend), o.command_line, setup.camera.width, setup.camera.height, setup.spp,
      o.orbit_frames, o.reference_spp);
  for (std::size_t i = 0; i < spp.size(); ++i) {
    const bool power_of_two = (spp[i] & (spp[i] - 1)) == 0;
    if (!power_of_two && i + 1 != spp.size()) continue;
    table += fmt::format("| {} | {:.2f} | {:.2f} | {:.4f} | {:.0f} | {:.2f} | {:.4f} | {:.0f} | {:.4f} | {:.4f} |\n",
                         spp[i], raw.psnr[i], before.psnr[i], before.ssim[i], before.ms[i], after.psnr[i],
                         after.ssim[i], after.ms[i], estimate[i], measured[i]);
  }
  auto reach = [&](const Curve& c, double db) {
    const int i = FirstAt(c, db);
    return i < 0 ? std::string("never") : fmt::format("{} spp, {:.0f} ms", spp[std::size_t(i)], c.ms[std::size_t(i)]);
  };
  table += fmt::format("\nlargest drop from one frame to the next: previous {:.2f} dB, refined {:.2f} dB; "
                       "40 dB reached: previous {}, refined {}; final: previous {:.2f} dB, refined {:.2f} dB\n",
                       LargestDrop(before), LargestDrop(after), reach(before, 40), reach(after, 40),
                       before.psnr.back(), after.psnr.back());
  for (int at : {16, 32, 64}) {  // the refined still against the raw mean of the same samples
    const auto i = std::find(spp.begin(), spp.end(), at) - spp.begin();
    if (std::size_t(i) == spp.size()) continue;
    table += fmt::format("at {} spp: raw mean {:.2f} dB, refined {:.2f} dB ({:+.2f} dB)\n", at, raw.psnr[i],
                         after.psnr[i], after.psnr[i] - raw.psnr[i]);
  }
  for (float target : {0.03f, 0.02f, 0.01f}) {
    std::size_t i = 0;
    while (i + 1 < spp.size() && !(estimate[i] >= 0 && estimate[i] <= target)) ++i;
    table += fmt::format("error target {}: stops at {} spp ({:.0f} ms), PSNR {:.2f} dB, SSIM {:.4f}\n", target,
                         spp[i], after.ms[i], after.psnr[i], after.ssim[i]);
  }
  Report(o, table);
  if (!o.csv.empty()) {
    const bool fresh = !std::filesystem::exists(o.csv);
    std::ofstream csv(o.csv, std::ios::app);
    if (fresh)
      csv << "scene,width,height,step,spp,previous_psnr,previous_ssim,previous_ms,psnr,ssim,ms,estimate,measured\n";
    for (std::size_t i = 0; i < spp.size(); ++i) {
      csv << fmt::format("{},{},{},{},{},{:.4f},{:.5f},{:.1f},{:.4f},{:.5f},{:.1f},{:.5f},{:.5f}\n", o.scene,
                         setup.camera.width, setup.camera.height, i, spp[i], before.psnr[i], before.ssim[i],
                         before.ms[i], after.psnr[i], after.ssim[i], after.ms[i], estimate[i], measured[i]);
    }
  }
  return 0;
}

}  // namespace cinevol::bench
