// `cinevol-bench denoise`: every denoiser on the same rendered camera orbit
// at the scene's spp per frame: milliseconds per frame and PSNR against a
// high-spp render of every frame, while the camera moves. Each method runs
// in a FramePipeline of its own, as a session would.
#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "bench.h"
#include "image_metrics.h"
#include "core/ycc.h"
#include "pipeline/frame_pipeline.h"
#include "tradeoff_study.h"

namespace cinevol::bench {
namespace {

struct Method {
  DenoiseMethod method;
  bool demodulate;
};

}  // namespace

int RunDenoiseBench(const DenoiseBenchOptions& o) {
  const LoadedScene loaded = LoadScene(o);
  const RenderSetup& setup = loaded.setup;
  const Backend backend = Resolve(ParseBackend(o.backend), "denoise bench");
  auto view = [&](int t) {
    RenderSetup v = setup;
    v.camera = Orbit(setup.camera, o.degrees_per_frame * float(t));
    return v;
  };

  std::vector<ImageRgbF> references;
  for (int t = 0; o.reference_spp > 0 && t < o.frames; ++t) {
    references.push_back(RenderReference(backend, loaded.volume, view(t), o.reference_spp, setup.max_bounces, t));
  }

  const Method methods[] = {{DenoiseMethod::kNone, false},         {DenoiseMethod::kAccumulate, false},
                            {DenoiseMethod::kKnn, false},          {DenoiseMethod::kGuidedFilter, false},
                            {DenoiseMethod::kSvgf, false},         {DenoiseMethod::kSvgf, true},
                            {DenoiseMethod::kWrls, false},         {DenoiseMethod::kWrls, true}};
  std::string table = fmt::format(
      "\n### Denoisers on {} ({})\n\n`{}`\n\n{}x{}, {} spp/frame, camera orbiting {} degrees per frame, {} frames; "
      "times: median over frames {}..{}; PSNR (tone-mapped) against {} spp per frame, mean over the same frames; "
      "flicker: RMS change between consecutive tone-mapped outputs of a static camera (the same frames again, "
      "camera still; the noisy input's is the first row)\n\n"
      "| method | demodulated | median ms | p90 ms | PSNR dB (moving) | flicker (static) "
      "|\n|---|---|---|---|---|---|\n",
      o.scene, DeviceDescription(o.backend), o.command_line, setup.camera.width, setup.camera.height, setup.spp,
      o.degrees_per_frame, o.frames, o.warmup, o.frames - 1, o.reference_spp);
  for (const Method& m : methods) {
    FrameSettings settings;
    settings.denoiser.method = m.method;
    settings.denoiser.demodulate = m.demodulate;
    settings.refine = false;  // the denoiser's output alone, however many samples pile up
    settings.chroma = ChromaSubsampling::k444;  // flicker on the displayed pixels, before JPEG
    // The same seed renders the same noisy frames for every method: frame t
    // of a fresh pipeline is sampled as frame t.
    FramePipeline moving(backend, loaded.volume);
    std::vector<double> ms;
    double psnr = 0;
    for (int t = 0; t < o.frames; ++t) {
      moving.Update(view(t), settings, kCameraChanged);
      const DisplayFrame frame = moving.RenderFrame();
      if (t < o.warmup) continue;
      ms.push_back(frame.denoise_ms);
      if (!references.empty()) psnr += DisplayPsnr(moving.DenoisedRadiance(), references[t]) / (o.frames - o.warmup);
    }
    // Flicker on a static camera: frame-to-frame change of what the viewer sees.
    FramePipeline still(backend, loaded.volume);
    still.Update(view(0), settings);
    double flicker = 0;
    ImageRgb8 previous;
    for (int t = 0; t < o.frames; ++t) {
      const ImageRgb8 shown = ToRgb(still.RenderFrame().image);
      if (t > o.warmup) flicker += RmsDifference(shown, previous) / (o.frames - o.warmup - 1);
      previous = shown;
    }
    std::sort(ms.begin(), ms.end());
    table += fmt::format("| {} | {} | {:.3f} | {:.3f} | {} | {:.4f} |\n", ToString(m.method),
                         m.demodulate ? "yes" : "no", ms[ms.size() / 2], ms[ms.size() * 9 / 10],
                         references.empty() ? std::string("-") : fmt::format("{:.2f}", psnr), flicker);
  }
  Report(o, table);
  return 0;
}

}  // namespace cinevol::bench
