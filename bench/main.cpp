// cinevol-bench: measurements for docs/performance.md.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <fstream>

#include "bench.h"
#include "core/error.h"
#include "core/parallel_for.h"
#include "io/label_volume.h"
#include "io/reader_cage.h"
#include "io/volume_loader.h"
#include "render/renderer.h"
#include "resampled_volume.h"
#include "scene/scene_file.h"
#include "scene/scene_frame.h"
#include "tradeoff_study.h"

namespace cinevol::bench {

void AddSceneOptions(CLI::App* c, SceneOptions& o) {
  c->add_option("--scene", o.scene, "Scene file")->required();
  c->add_option("--volume", o.volume, "Volume file, folder or phantom: overrides the scene's");
  c->add_option("--labels", o.labels, "Label volume: overrides the scene's volume.labels");
  c->add_option("--backend", o.backend, "auto, cpu or cuda");
  c->add_option("--width", o.width, "Frame width (default: the scene's)");
  c->add_option("--height", o.height, "Frame height (default: the scene's)");
  c->add_option("--out", o.out, "Append the Markdown table to this file");
}

LoadedScene LoadScene(const SceneOptions& o) {
  LoadedScene s;
  s.scene = LoadSceneFile(o.scene);
  if (!o.volume.empty()) *s.scene.mutable_volume() = ParseVolumeSpec(o.volume);
  if (o.width > 0) s.scene.mutable_render()->set_width(o.width);
  if (o.height > 0) s.scene.mutable_render()->set_height(o.height);
  if (!o.labels.empty()) s.scene.mutable_volume()->set_labels(o.labels);
  s.volume = std::make_shared<const Volume>(LoadVolume(s.scene.volume()));
  ToVolumeFrame(s.scene, VolumePlacement::Of(*s.volume));  // the renderers' frame
  s.labels = LoadSceneLabels(s.scene, *s.volume);          // with the table where the scene removes it
  s.setup = ResolveScene(s.scene, *s.volume, s.labels.get(),
                         [](const std::string& map) { return reader_cage::ReadEnvironmentMap(map); });
  return s;
}

void Report(const SceneOptions& o, const std::string& table) {
  std::fputs(table.c_str(), stdout);
  if (!o.out.empty()) std::ofstream(o.out, std::ios::app) << table;
}

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
  auto* r =
      app.add_subcommand("render", "Path tracer ms/frame with and without empty-space skipping and specialisation");
  cinevol::bench::AddSceneOptions(r, render);
  r->add_option("--frames", render.frames, "Timed frames")->capture_default_str();
  r->add_option("--warmup", render.warmup, "Untimed frames first")->capture_default_str();
  r->add_flag("--default-only", render.default_only, "Only the default configuration (its first row)");
  r->callback([&] { cinevol::bench::RunRenderBench(render); });
  cinevol::bench::DenoiseBenchOptions denoise;
  denoise.command_line = command_line;
  auto* d = app.add_subcommand("denoise", "Every denoiser on a rendered camera orbit: ms/frame and PSNR");
  cinevol::bench::AddSceneOptions(d, denoise);
  d->add_option("--frames", denoise.frames, "Frames in the orbit")->capture_default_str();
  d->add_option("--warmup", denoise.warmup, "Frames before measuring")->capture_default_str();
  d->add_option("--reference-spp", denoise.reference_spp, "Samples per pixel of the reference (0: no PSNR)")
      ->capture_default_str();
  d->add_option("--degrees-per-frame", denoise.degrees_per_frame, "Camera orbit speed")->capture_default_str();
  d->add_option("--variant", denoise.variants, "NAME:key=value,...: a wRLS or SVGF variant, one more row (repeatable)");
  d->callback([&] { cinevol::bench::RunDenoiseBench(denoise); });
  cinevol::bench::EncodeBenchOptions encode;
  encode.command_line = command_line;
  auto* j = app.add_subcommand("encode", "A frame's JPEG on the CPU and with nvJPEG on the GPU: ms, bytes, PSNR");
  cinevol::bench::AddSceneOptions(j, encode);
  j->add_option("--frames", encode.frames, "Timed frames")->capture_default_str();
  j->add_option("--warmup", encode.warmup, "Untimed frames first")->capture_default_str();
  j->add_option("--quality", encode.quality, "JPEG quality")->check(CLI::Range(1, 100))->capture_default_str();
  j->add_option("--degrees-per-frame", encode.degrees_per_frame, "Camera orbit speed")->capture_default_str();
  j->add_option("--jpeg-encoder", encode.jpeg_encoder,
                "auto (on a GPU: cinevol's coder, and nvJPEG where it loads, beside the CPU), cpu (the CPU alone), "
                "cuda or nvjpeg (that one beside the CPU; refused where it cannot run)")
      ->check(CLI::IsMember({"auto", "cpu", "cuda", "nvjpeg"}))
      ->capture_default_str();
  j->callback([&] { cinevol::bench::RunEncodeBench(encode); });
  cinevol::bench::RefineBenchOptions refine;
  refine.command_line = command_line;
  auto* f =
      app.add_subcommand("refine", "Still frames after an orbit: displayed PSNR/SSIM per step, refined and previous");
  cinevol::bench::AddSceneOptions(f, refine);
  f->add_option("--reference-spp", refine.reference_spp, "Samples per pixel of the reference")->capture_default_str();
  f->add_option("--target-spp", refine.target_spp, "Samples per pixel the curve runs to")->capture_default_str();
  f->add_option("--orbit-frames", refine.orbit_frames, "Camera moves before it holds still")->capture_default_str();
  f->add_option("--csv", refine.csv, "Append every step (spp, ms, PSNR, SSIM, errors) to this CSV");
  f->add_option("--variant", refine.variant,
                 "NAME:key=value,...: the denoiser's settings as tradeoff's --variant (spp: the scene's)");
  f->add_option("--reference", refine.reference, "EXR of the reference: read where it exists, else written");
  f->add_option("--still-ramp", refine.still_ramp,
                 "Still frames of the scene's spp, then twice the last up to this many (a CPU session's; 0: off)")
      ->check(CLI::Range(0, 1024));
  f->add_option("--seed", refine.seed, "The frames' seed instead of the scene's")->check(CLI::Range(0, 1 << 30));
  f->callback([&] { cinevol::bench::RunRefineBench(refine); });
  cinevol::bench::EventBenchOptions events;
  events.command_line = command_line;
  auto* e = app.add_subcommand("events", "What a camera event costs the server before a frame renders, per step");
  cinevol::bench::AddSceneOptions(e, events);
  e->add_option("--events", events.events, "Camera events")->check(CLI::Range(1, 1000000))->capture_default_str();
  e->callback([&] { cinevol::bench::RunEventBench(events); });
  cinevol::bench::VolumeBenchOptions volume;
  volume.command_line = command_line;
  auto* v = app.add_subcommand("volume", "Load, histogram and block ranges, kind and framing, per volume");
  v->add_option("volumes", volume.volumes, "Volume files, DICOM folders or phantom specs")->required();
  v->add_option("--out", volume.out, "Append the Markdown table to this file");
  v->callback([&] { cinevol::bench::RunVolumeBench(volume); });

  cinevol::bench::CageBenchOptions cage;
  cage.command_line = command_line;
  auto* g = app.add_subcommand("cage", "Loads through the reader cage against loads in this process, per volume");
  g->add_option("volumes", cage.volumes, "Volume files or DICOM folders")->required();
  g->add_option("--runs", cage.runs, "Loads each way (medians)")->check(CLI::Range(1, 1000));
  g->add_option("--out", cage.out, "Append the Markdown table to this file");
  g->callback([&] { cinevol::bench::RunCageBench(cage); });

  cinevol::bench::ScaleBenchOptions scale;
  scale.command_line = command_line;
  auto* sc =
      app.add_subcommand("scale", "A CT resampled to more slices: load to first frame, frame time, memory (GPU)");
  sc->add_option("--volume", scale.volume, "The CT to resample")->required();
  sc->add_option("--slices", scale.slices, "Slice counts, one row each (comma-separated)")
      ->check(CLI::Range(1, 8192))
      ->delimiter(',')
      ->capture_default_str();
  sc->add_option("--pixels", scale.pixels, "Pixels along each slice's edge")->check(CLI::Range(16, 1024));
  sc->add_option("--slice-mm", scale.slice_mm, "Distance between slices")->check(CLI::Range(0.1f, 10.0f));
  sc->add_option("--frames", scale.frames, "720p frames timed after the first")->check(CLI::Range(1, 1000));
  sc->add_option("--sessions", scale.sessions, "Sessions the room left for a volume is counted beside");
  sc->add_option("--scratch", scale.scratch, "Folder for the resampled files (removed after each row)");
  sc->add_option("--out", scale.out, "Append the Markdown table to this file");
  sc->callback([&] { cinevol::bench::RunScaleBench(scale); });

  std::string resample_volume, resample_out;
  std::vector<int> resample_size;
  auto* rs = app.add_subcommand("resample", "A volume resampled onto another grid over its box, as a 16-bit NRRD");
  rs->add_option("--volume", resample_volume, "Volume file, folder or phantom")->required();
  rs->add_option("--size", resample_size, "Voxels along x,y,z (comma-separated)")
      ->required()
      ->expected(3)
      ->delimiter(',')
      ->check(CLI::Range(1, 8192));
  rs->add_option("--out", resample_out, "The NRRD to write")->required();
  rs->callback([&] {
    cinevol::bench::RunResample(resample_volume, {resample_size[0], resample_size[1], resample_size[2]}, resample_out);
  });

  cinevol::bench::ReconstructionBenchOptions reconstruction;
  reconstruction.command_line = command_line;
  reconstruction.width = reconstruction.height = 512;
  auto* c = app.add_subcommand("reconstruction", "Trilinear against tricubic on a coarse ball, against a fine one");
  c->add_option("--spacing", reconstruction.spacings, "Coarse spacings, mm (repeatable)")->capture_default_str();
  c->add_option("--reference-spacing", reconstruction.reference_spacing, "The reference's spacing, mm")
      ->capture_default_str();
  c->add_option("--spp", reconstruction.spp, "Samples per pixel of every image")->capture_default_str();
  c->add_option("--width", reconstruction.width, "Image width")->capture_default_str();
  c->add_option("--height", reconstruction.height, "Image height")->capture_default_str();
  c->add_option("--frames", reconstruction.frames, "Timed 720p frames")->capture_default_str();
  c->add_option("--warmup", reconstruction.warmup, "Untimed 720p frames first")->capture_default_str();
  c->add_option("--backend", reconstruction.backend, "auto, cpu or cuda")->capture_default_str();
  c->add_option("--images", reconstruction.images, "Write the images to this folder");
  c->add_option("--out", reconstruction.out, "Append the Markdown table to this file");
  c->callback([&] { cinevol::bench::RunReconstructionBench(reconstruction); });

  cinevol::bench::CallsBenchOptions calls;
  calls.command_line = command_line;
  auto* k =
      app.add_subcommand("calls", "GetStatus and health latency while clients create sessions on a labelled volume");
  k->add_option("--server", calls.server, "A running server (default: start one on a written volume)");
  k->add_option("--token", calls.token, "Bearer token for --server");
  k->add_option("--volume", calls.volume, "With --server: the id of a volume that has a segmentation");
  k->add_option("--size", calls.size, "Without --server: the written volume's side, voxels")
      ->check(CLI::Range(16, 1024))
      ->capture_default_str();
  k->add_option("--clients", calls.clients, "Clients creating sessions at once")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  k->add_option("--creations", calls.creations, "Sessions each client creates and closes in turn")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  k->add_option("--width", calls.width, "Session viewport width")->capture_default_str();
  k->add_option("--height", calls.height, "Session viewport height")->capture_default_str();
  k->add_option("--interval-ms", calls.interval_ms, "Pause between probes")->capture_default_str();
  k->add_option("--out", calls.out, "Append the Markdown table to this file");
  k->callback([&] {
    if (cinevol::bench::RunCallsBench(calls) != 0) throw CLI::RuntimeError(1);
  });

  // The speed/accuracy study: --dataset NAME=SCENE[,VOLUME] (repeatable).
  cinevol::bench::StudyOptions study;
  study.command_line = command_line;
  std::vector<std::string> datasets, scenarios, variants;
  bool quick = false;
  std::string out = "tradeoff-results", cache = "bench-cache";
  auto* t = app.add_subcommand("tradeoff", "Quality against time per frame for every knob, on the paper's scenarios");
  t->add_option("--dataset", datasets,
                "NAME=SCENE_FILE[,VOLUME] (repeatable); SCENE_FILE preset:NAME or preset:default is a session's "
                "scene for that preset (with VOLUME)")
      ->required();
  t->add_option("--scenario", scenarios,
                "orbit, area-light, point-light, tf-edit, static, transparent, sun-sky, beat (a time series: its "
                "phases with the view still) (default all)");
  t->add_option("--width", study.width, "Frame width")->capture_default_str();
  t->add_option("--height", study.height, "Frame height")->capture_default_str();
  t->add_option("--frames-scale", study.frames_scale, "Scenario lengths times this")->capture_default_str();
  t->add_option("--reference-spp", study.reference_spp, "Samples per pixel of the references (two halves)")
      ->check(CLI::Range(1, 1 << 16))
      ->capture_default_str();
  t->add_option("--reference-bounces", study.reference_bounces,
                "Bounces of the bounces sweep's references (the others: their own)")
      ->capture_default_str();
  t->add_option("--cache", cache, "Folder of cached reference EXRs")->capture_default_str();
  t->add_option("--out", out, "Results folder: tradeoff.csv, .json, .md, images/")->capture_default_str();
  t->add_option("--backend", study.backend, "auto, cpu or cuda")->capture_default_str();
  t->add_flag("--quick", quick, "A small subset of the configurations");
  t->add_option("--variant", variants,
                "Also a wRLS (or method=svgf) variant NAME:key=value,... (repeatable; ablations)");
  bool variants_only = false;
  t->add_flag("--variants-only", variants_only, "Only none, svgf, the default wrls and the variants");
  bool denoisers_only = false;
  t->add_flag("--denoisers-only", denoisers_only, "Every denoiser, no sweeps of the other knobs");
  std::string knob;
  t->add_option("--knob", knob, "Only the default wRLS and this knob's sweep: spp, bounces, jpeg or scale");
  t->callback([&] {
    for (const std::string& spec : datasets) {
      const auto eq = spec.find('='), comma = spec.find(',', eq);
      if (eq == std::string::npos) throw cinevol::InputError("--dataset " + spec + ": use NAME=SCENE_FILE[,VOLUME]");
      study.datasets.push_back({spec.substr(0, eq),
                                spec.substr(eq + 1, comma == std::string::npos ? comma : comma - eq - 1),
                                comma == std::string::npos ? "" : spec.substr(comma + 1)});
    }
    study.scenarios = scenarios;
    study.configs = cinevol::bench::StudyConfigs(quick);
    if (variants_only) {
      std::erase_if(study.configs, [](const auto& c) {
        return c.knob != "denoiser" || c.demodulate ||
               (c.method != cinevol::DenoiseMethod::kNone && c.method != cinevol::DenoiseMethod::kSvgf &&
                c.method != cinevol::DenoiseMethod::kWrls);
      });
    }
    if (denoisers_only) std::erase_if(study.configs, [](const auto& c) { return c.knob != "denoiser"; });
    if (!knob.empty()) {
      if (std::none_of(study.configs.begin(), study.configs.end(), [&](const auto& c) { return c.knob == knob; })) {
        throw cinevol::InputError("--knob " + knob + ": not a knob this study sweeps (spp, bounces, jpeg, scale)");
      }
      std::erase_if(study.configs, [&](const auto& c) {
        const bool default_wrls = c.knob == "denoiser" && c.method == cinevol::DenoiseMethod::kWrls && !c.demodulate;
        return c.knob != knob && !default_wrls;
      });
    }
    for (const std::string& v : variants) study.configs.push_back(cinevol::bench::Variant(v));
    study.cache = cache;
    study.out = out;
    const auto results = cinevol::bench::RunStudy(study);
    std::fputs(cinevol::bench::SummaryTable(results).c_str(), stdout);
  });
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
