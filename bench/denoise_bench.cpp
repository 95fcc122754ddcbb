// `cinevol-bench denoise`: every denoiser on the same rendered camera orbit
// at the scene's spp per frame: milliseconds per frame and PSNR against a
// high-spp render of every frame, while the camera moves.
#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "bench.h"
#include "core/image_metrics.h"
#include "core/tone_map.h"
#include "denoise/denoiser.h"
#include "render/renderer.h"
#include "tradeoff_study.h"

namespace cinevol::bench {
namespace {


// RMS difference of two 8-bit images, in [0, 1] units.
double RmsDifference(const ImageRgb8& a, const ImageRgb8& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.bytes.size(); ++i) sum += Sqr((float(a.bytes[i]) - float(b.bytes[i])) / 255.0f);
  return std::sqrt(sum / double(a.bytes.size()));
}

struct Method {
  DenoiseMethod method;
  bool demodulate;
};

}  // namespace

int RunDenoiseBench(const DenoiseBenchOptions& o) {
  const LoadedScene loaded = LoadScene(o);
  const RenderSetup& setup = loaded.setup;
  const Backend backend = ParseBackend(o.backend);
  auto renderer = CreateRenderer(backend);
  renderer->SetVolume(loaded.volume);
  renderer->SetTransferFunction(setup.transfer_function);
  renderer->SetLights(setup.lights);
  const Backend denoise_backend = renderer->backend();

  auto request = [&](int t, int spp, std::uint64_t seed) {
    FrameRequest r;
    r.camera = Orbit(setup.camera, o.degrees_per_frame * float(t));
    r.spp = spp;
    r.max_bounces = setup.max_bounces;
    r.seed = seed;
    r.frame = static_cast<std::uint32_t>(t);
    return r;
  };

  std::vector<ImageRgbF> references;
  for (int t = 0; o.reference_spp > 0 && t < o.frames; ++t) {
    const Camera camera = Orbit(setup.camera, o.degrees_per_frame * float(t));
    references.push_back(RenderReference(*renderer, camera, o.reference_spp, setup.max_bounces, t));
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
      "| method | demodulated | median ms | p90 ms | PSNR dB (moving) | flicker (static) |\n|---|---|---|---|---|---|\n",
      o.scene, DeviceDescription(o.backend), o.command_line, setup.camera.width, setup.camera.height, setup.spp,
      o.degrees_per_frame, o.frames, o.warmup, o.frames - 1, o.reference_spp);
  for (const Method& m : methods) {
    DenoiserSettings settings;
    settings.method = m.method;
    settings.demodulate = m.demodulate;
    auto denoiser = CreateDenoiser(denoise_backend, settings);
    std::vector<double> ms;
    double psnr = 0;
    for (int t = 0; t < o.frames; ++t) {
      const FrameRequest r = request(t, setup.spp, setup.seed);
      renderer->Render(r);  // the same seed renders the same noisy frame for every method
      const FrameTargets in = renderer->Targets();
      denoiser->Denoise({r.camera.width, r.camera.height, in.radiance, in.first_hit, in.albedo, r.camera, 0});
      const double t_ms = denoiser->LastMilliseconds();
      if (t < o.warmup) continue;
      ms.push_back(t_ms);
      if (!references.empty()) psnr += DisplayPsnr(denoiser->Output(), references[t]) / (o.frames - o.warmup);
    }
    // Flicker on a static camera: frame-to-frame change of what the viewer sees.
    denoiser->Reset();
    double flicker = 0;
    ImageRgb8 previous;
    for (int t = 0; t < o.frames; ++t) {
      FrameRequest r = request(0, setup.spp, setup.seed);
      r.frame = static_cast<std::uint32_t>(t);
      renderer->Render(r);
      const FrameTargets in = renderer->Targets();
      denoiser->Denoise({r.camera.width, r.camera.height, in.radiance, in.first_hit, in.albedo, r.camera, 0});
      const ImageRgb8 shown = ToneMap(denoiser->Output(), 0.0f);
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
