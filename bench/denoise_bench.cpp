// `cinevol-bench denoise`: every denoiser on the same rendered camera orbit
// at the scene's spp per frame: milliseconds per frame and PSNR against a
// high-spp render of every frame, while the camera moves. Each method runs
// in a FramePipeline of its own, as a session would.
#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "bench.h"
#include "core/error.h"
#include "image_metrics.h"
#include "core/ycc.h"
#include "pipeline/frame_pipeline.h"
#include "tradeoff_study.h"

namespace cinevol::bench {
namespace {

struct Method {
  std::string label;
  DenoiserSettings settings;
  bool hold_codes = true;  // FrameSettings::hold_codes
};

Method Plain(DenoiseMethod method, bool demodulate) {
  Method m{ToString(method), {}};
  m.settings.method = method;
  m.settings.demodulate = demodulate;
  return m;
}

// Every denoiser, plainly and demodulated, then the options' variants.
std::vector<Method> Methods(const DenoiseBenchOptions& o) {
  std::vector<Method> methods = {Plain(DenoiseMethod::kNone, false),         Plain(DenoiseMethod::kAccumulate, false),
                                 Plain(DenoiseMethod::kKnn, false),          Plain(DenoiseMethod::kGuidedFilter, false),
                                 Plain(DenoiseMethod::kSvgf, false),         Plain(DenoiseMethod::kSvgf, true),
                                 Plain(DenoiseMethod::kWrls, false),         Plain(DenoiseMethod::kWrls, true)};
  for (const std::string& spec : o.variants) {
    const StudyConfig c = Variant(spec);
    if (c.spp != StudyConfig{}.spp) throw InputError(fmt::format("--variant {}: the bench renders the scene's spp", spec));
    Method m = Plain(c.method, false);
    m.label = c.Label();
    m.settings.wrls = c.wrls;
    m.settings.svgf = c.svgf;
    m.hold_codes = c.hold_codes;
    methods.push_back(m);
  }
  return methods;
}

}  // namespace

int RunDenoiseBench(const DenoiseBenchOptions& o) {
  const std::vector<Method> methods = Methods(o);  // bad variants fail before any rendering
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
    references.push_back(RenderReference(backend, loaded.volume, view(t), o.reference_spp, setup.max_bounces));
  }

  std::string table = fmt::format(
      "\n### Denoisers on {} ({})\n\n`{}`\n\n{}x{}, {} spp/frame, camera orbiting {} degrees per frame, {} frames; "
      "times: median over frames {}..{}; PSNR (tone-mapped) against {} spp per frame, mean over the same frames; "
      "level: the mean luminance's offset from the reference's (a bias the PSNR hides in), same frames; "
      "flicker: RMS change between consecutive tone-mapped outputs of a static camera (the same frames again, "
      "camera still; the noisy input's is the first row), and the same before 8-bit rounding; PSNR (static): those "
      "frames against the first frame's reference\n\n"
      "| method | demodulated | median ms | p90 ms | PSNR dB (moving) | level % | flicker (static) "
      "| before rounding | PSNR dB (static) |\n|---|---|---|---|---|---|---|---|---|\n",
      o.scene, DeviceDescription(o.backend), o.command_line, setup.camera.width, setup.camera.height, setup.spp,
      o.degrees_per_frame, o.frames, o.warmup, o.frames - 1, o.reference_spp);
  for (const Method& m : methods) {
    FrameSettings settings;
    settings.denoiser = m.settings;
    settings.hold_codes = m.hold_codes;
    settings.refine = false;  // the denoiser's output alone, however many samples pile up
    settings.chroma = ChromaSubsampling::k444;  // flicker on the displayed pixels, before JPEG
    // The same seed renders the same noisy frames for every method: frame t
    // of a fresh pipeline is sampled as frame t.
    FramePipeline moving(backend, loaded.volume);
    std::vector<double> ms;
    double psnr = 0, level = 0;
    for (int t = 0; t < o.frames; ++t) {
      moving.Update(view(t), settings, kCameraChanged);
      const DisplayFrame frame = moving.RenderFrame();
      if (t < o.warmup) continue;
      ms.push_back(frame.denoise_ms);
      if (references.empty()) continue;
      const ImageRgbF denoised = moving.DenoisedRadiance();
      psnr += DisplayPsnr(denoised, references[t]) / (o.frames - o.warmup);
      level += LevelBias(denoised, references[t]) / (o.frames - o.warmup);
    }
    // Flicker on a static camera: frame-to-frame change of what the viewer sees.
    FramePipeline still(backend, loaded.volume);
    still.Update(view(0), settings);
    double flicker = 0, unrounded = 0, still_psnr = 0;
    ImageRgb8 previous;
    ImageRgbF previous_radiance;
    for (int t = 0; t < o.frames; ++t) {
      const ImageRgb8 shown = ToRgb(still.RenderFrame().image);
      ImageRgbF radiance = still.DenoisedRadiance();
      if (t > o.warmup) {
        flicker += RmsDifference(shown, previous) / (o.frames - o.warmup - 1);
        unrounded += DisplayRmsDifference(radiance, previous_radiance) / (o.frames - o.warmup - 1);
        if (!references.empty()) still_psnr += DisplayPsnr(radiance, references[0]) / (o.frames - o.warmup - 1);
      }
      previous = shown;
      previous_radiance = std::move(radiance);
    }
    std::sort(ms.begin(), ms.end());
    auto measured = [&](const char* format, double value) {
      return references.empty() ? std::string("-") : fmt::format(fmt::runtime(format), value);
    };
    table += fmt::format("| {} | {} | {:.3f} | {:.3f} | {} | {} | {:.4f} | {:.4f} | {} |\n", m.label,
                         m.settings.demodulate ? "yes" : "no", ms[ms.size() / 2], ms[ms.size() * 9 / 10],
                         measured("{:.2f}", psnr), measured("{:+.2f}", 100 * level), flicker, unrounded,
                         measured("{:.2f}", still_psnr));
  }
  Report(o, table);
  return 0;
}

}  // namespace cinevol::bench
