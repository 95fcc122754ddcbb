// `cinevol-bench render`: milliseconds per frame and paths per second of the
// path tracer on a scene, with empty-space skipping and specialisation each
// switched on and off in the same run, each in a FramePipeline of its own;
// trilinear unless a row says tricubic.
// Prints a Markdown table (and appends it to --out) for docs/performance.md.
#include <algorithm>
#include <chrono>

#include <fmt/format.h>

#include "bench.h"
#include "pipeline/frame_pipeline.h"

namespace cinevol::bench {
namespace {

struct Config {
  std::string name;
  int brick_size;  // 0: one global majorant
  bool specialised;
  bool volume_texture = true;
  Reconstruction reconstruction = Reconstruction::kTrilinear;
};

struct Result {
  double median_ms, p10_ms, p90_ms, paths_per_second;
  unsigned features;
};

Result Measure(const RenderBenchOptions& o, const Config& c, const LoadedScene& loaded) {
  const RenderSetup& setup = loaded.setup;
  RendererOptions options;
  options.brick_size = c.brick_size;
  options.volume_texture = c.volume_texture;
  FramePipeline pipeline(ParseBackend(o.backend), loaded.volume, options, loaded.labels);
  pipeline.SetRenderFeatures(c.specialised ? kAutoFeatures : kAllFeatures);
  FrameSettings settings;
  settings.denoiser.method = DenoiseMethod::kNone;  // the renderer's time is what is measured
  RenderSetup with = setup;
  with.reconstruction = c.reconstruction;
  pipeline.Update(with, settings);
  std::vector<double> ms;
  for (int f = 0; f < o.warmup + o.frames; ++f) {
    const double t = pipeline.RenderFrame().render_ms;
    if (f >= o.warmup) ms.push_back(t);
  }
  std::sort(ms.begin(), ms.end());
  const double median = ms[ms.size() / 2];
  const double paths = double(setup.camera.width) * setup.camera.height * setup.spp;
  return {median, ms[ms.size() / 10], ms[ms.size() * 9 / 10], paths / (median / 1000.0),
          pipeline.last_render_features()};
}

}  // namespace

int RunRenderBench(const RenderBenchOptions& o) {
  const LoadedScene loaded = LoadScene(o);
  const auto& volume = loaded.volume;
  const RenderSetup& setup = loaded.setup;
  const std::string device = DeviceDescription(o.backend);

  std::string table = fmt::format(
      "\n### {} on {}\n\n`{}`\n\nvolume {} ({}x{}x{}), {}x{}, {} spp/frame, up to {} bounces, {} lights + "
      "environment; median of {} frames after {} warm-up\n\n"
      "| configuration | features | median ms/frame | p10..p90 ms | Mpaths/s |\n|---|---|---|---|---|\n",
      o.scene, device, o.command_line, volume->metadata().source, volume->dims().x, volume->dims().y,
      volume->dims().z, setup.camera.width, setup.camera.height, setup.spp, setup.max_bounces,
      setup.lights.lights.size(), o.frames, o.warmup);
  if (loaded.labels) {
    table.insert(table.find("| configuration"), fmt::format("segmentation {} with {} label styles\n\n",
                                                            loaded.labels->source, loaded.setup.labels.styles.size()));
  }
  const int auto_bricks = BrickSizeFor(*volume);
  std::vector<Config> configs = {
      {fmt::format("default: {}^3 bricks (for its spacing), specialised", auto_bricks), kAutoBrickSize, true},
      {"no empty-space skipping (global majorant)", 0, true},
      {"no specialisation (all features)", kAutoBrickSize, false},
      {"neither", 0, false}};
  for (int b : {2, 3, 4, 8, 16}) {
    if (b != auto_bricks) configs.push_back({fmt::format("{}^3 bricks, specialised", b), b, true});
  }
  if (ParseBackend(o.backend) != Backend::kCpu) {
    configs.push_back({"voxels read from a buffer, not the texture unit", kAutoBrickSize, true, false});
  }
  configs.push_back({"tricubic reconstruction", kAutoBrickSize, true, true, Reconstruction::kTricubic});
  if (o.default_only) configs.resize(1);
  double base = 0;
  for (const Config& c : configs) {
    const Result r = Measure(o, c, loaded);
    if (base == 0) base = r.median_ms;
    table += fmt::format("| {} | {:#04x} | {:.3f} ({:.2f}x) | {:.3f}..{:.3f} | {:.1f} |\n", c.name, r.features,
                         r.median_ms, r.median_ms / base, r.p10_ms, r.p90_ms, r.paths_per_second / 1e6);
  }
  Report(o, table);
  return 0;
}

}  // namespace cinevol::bench
