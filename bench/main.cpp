// cinevol-bench: measurements for docs/performance.md.
#include <CLI/CLI.hpp>

#include <cstdio>

#include "bench.h"
#include "core/error.h"
#include "core/parallel_for.h"
#include "render/renderer.h"

namespace cinevol::bench {

std::string DeviceDescription(const std::string& backend) {
  std::string gpu;
  const bool cuda = CudaAvailable(&gpu);
  if (backend == "cuda" || (backend == "auto" && cuda)) return gpu + " (cuda)";
  return "cpu, " + std::to_string(DefaultThreadCount()) + " threads";
}

}  // namespace cinevol::bench

int main(int argc, char** argv) {
  CLI::App app{"cinevol-bench: renderer and denoiser measurements"};
  app.require_subcommand(1);
  std::string command_line = "cinevol-bench";
  for (int i = 1; i < argc; ++i) command_line += std::string(" ") + argv[i];

  cinevol::bench::RenderBenchOptions render;
  render.command_line = command_line;
  auto* r = app.add_subcommand("render", "Path tracer ms/frame with and without empty-space skipping and specialisation");
  r->add_option("--scene", render.scene, "Scene file")->required();
  r->add_option("--volume", render.volume, "Volume file, folder or phantom: overrides the scene's");
  r->add_option("--backend", render.backend, "auto, cpu or cuda");
  r->add_option("--width", render.width, "Frame width (default: the scene's)");
  r->add_option("--height", render.height, "Frame height (default: the scene's)");
  r->add_option("--frames", render.frames, "Timed frames")->capture_default_str();
  r->add_option("--warmup", render.warmup, "Untimed frames first")->capture_default_str();
  r->add_option("--out", render.out, "Append the Markdown table to this file");
  r->callback([&] { cinevol::bench::RunRenderBench(render); });
  cinevol::bench::DenoiseBenchOptions denoise;
  denoise.command_line = command_line;
  auto* d = app.add_subcommand("denoise", "Every denoiser on a rendered camera orbit: ms/frame and PSNR");
  d->add_option("--scene", denoise.scene, "Scene file")->required();
  d->add_option("--volume", denoise.volume, "Volume file, folder or phantom: overrides the scene's");
  d->add_option("--backend", denoise.backend, "auto, cpu or cuda (renderer and denoisers)");
  d->add_option("--width", denoise.width, "Frame width (default: the scene's)");
  d->add_option("--height", denoise.height, "Frame height (default: the scene's)");
  d->add_option("--frames", denoise.frames, "Frames in the orbit")->capture_default_str();
  d->add_option("--warmup", denoise.warmup, "Frames before measuring")->capture_default_str();
  d->add_option("--reference-spp", denoise.reference_spp, "Samples per pixel of the reference (0: no PSNR)")
      ->capture_default_str();
  d->add_option("--degrees-per-frame", denoise.degrees_per_frame, "Camera orbit speed")->capture_default_str();
  d->add_option("--out", denoise.out, "Append the Markdown table to this file");
  d->callback([&] { cinevol::bench::RunDenoiseBench(denoise); });
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cinevol-bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
