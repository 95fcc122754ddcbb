// cinevol-bench: quality and time measurements whose results go to
// docs/performance.md with the command that produced them.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "cinevol/v1/scene.pb.h"
#include "core/volume.h"
#include "scene/scene_builder.h"

namespace cinevol::bench {

// What every benchmark takes: a scene, optionally another volume and size.
struct SceneOptions {
  std::string scene;
  std::string volume;  // overrides the scene's volume (e.g. data copied to a GPU machine)
  std::string labels;  // overrides the scene's volume.labels
  std::string backend = "auto";
  std::string out;     // Markdown table appended here
  std::string command_line;
  int width = 0, height = 0;  // 0: the scene's
};

void AddSceneOptions(CLI::App* command, SceneOptions& options);

struct LoadedScene {
  v1::Scene scene;
  std::shared_ptr<const Volume> volume;
  std::shared_ptr<const LabelVolume> labels;  // the scene's segmentation, where it names one
  RenderSetup setup;
};

LoadedScene LoadScene(const SceneOptions& options);

// Appends `table` to options.out (when set) and prints it.
void Report(const SceneOptions& options, const std::string& table);

struct RenderBenchOptions : SceneOptions {
  int frames = 50, warmup = 5;
  bool default_only = false;
};

int RunRenderBench(const RenderBenchOptions& options);

struct DenoiseBenchOptions : SceneOptions {
  int frames = 24, warmup = 8;
  int reference_spp = 512;         // 0: timings only
  float degrees_per_frame = 1.0f;  // camera orbit speed
  std::vector<std::string> variants;  // "NAME:key=value,..." (tradeoff_study.h, Variant): more rows
};

int RunDenoiseBench(const DenoiseBenchOptions& options);

struct RefineBenchOptions : SceneOptions {
  int reference_spp = 4096;
  int target_spp = 512;    // the curve runs to this many samples per pixel
  int orbit_frames = 8;    // camera moves before it holds still
  std::string csv;         // every step's numbers, for plots (bench/plot_refine.py)
  std::string variant;     // the denoiser's settings changed as the study's --variant says (empty: the defaults)
  std::string reference;   // an EXR: the reference read from it where it exists, else rendered and written there
  int seed = -1;           // >= 0: the frames' seed instead of the scene's
  int still_ramp = 0;      // > 0: still frames take the scene's spp, then twice the last, up to this (a CPU session's)
};

// The displayed error of still frames after an orbit, refined against the
// previous release's blend.
int RunRefineBench(const RefineBenchOptions& options);

struct EventBenchOptions : SceneOptions {
  int events = 2000;
};

// What a camera event costs the server before a frame renders, step by step.
int RunEventBench(const EventBenchOptions& options);

struct EncodeBenchOptions : SceneOptions {
  int frames = 50, warmup = 5;
  int quality = 80;                 // [1, 100]
  float degrees_per_frame = 1.0f;   // camera orbit speed
  std::string jpeg_encoder = "auto";  // the GPU encoders measured beside the CPU (main.cpp's flag)
};

// A frame's JPEG on the CPU (whole and in bands) and with nvJPEG on the GPU:
// times, bytes and decoded PSNR.
int RunEncodeBench(const EncodeBenchOptions& options);

struct VolumeBenchOptions {
  std::vector<std::string> volumes;  // files, folders or phantom specs
  std::string out;
  std::string command_line;
};

// Load, summaries (histogram, block ranges), kind and framing per volume.
int RunVolumeBench(const VolumeBenchOptions& options);

struct ScaleBenchOptions {
  std::string volume;                      // the CT to resample
  std::vector<int> slices{256, 1024, 2048};
  int pixels = 512;                        // per slice edge
  float slice_mm = 0.8f;
  int frames = 30;
  int sessions = 32;                       // for the room left beside them
  std::string scratch;                     // where the resampled files go (removed after); default: temp
  std::string out;
  std::string command_line;
};
// A CT resampled to more and more slices: read, prepare, upload, first frame,
// frame time and memory (needs a GPU).
int RunScaleBench(const ScaleBenchOptions& options);

struct CageBenchOptions : VolumeBenchOptions {
  int runs = 7;  // loads each way, alternating
};

// Each volume loaded through the reader cage and in this process, and the
// server-side peak memory of the caged load.
int RunCageBench(const CageBenchOptions& options);

struct ReconstructionBenchOptions : SceneOptions {
  std::vector<float> spacings{2.0f, 3.0f};  // mm: the coarse balls
  float reference_spacing = 0.25f;
  int spp = 1024;
  int frames = 50, warmup = 10;  // 720p frames timed, after untimed ones
  std::string images;  // folder for the PNGs; empty: none
};

// Trilinear against tricubic on a coarse ball, with a fine ball as reference.
int RunReconstructionBench(const ReconstructionBenchOptions& options);

struct CallsBenchOptions {
  std::string server;  // empty: a cinevol-server of its own on a written volume of `size`^3
  std::string token;
  std::string volume;  // with --server: a volume that has a segmentation
  int size = 512;
  int clients = 4;     // creating sessions at once
  int creations = 1;   // sessions each client creates (and closes), one after another
  int width = 320, height = 180;
  int interval_ms = 10;  // between the prober's GetStatus + health rounds
  std::string out;
  std::string command_line;
};

// GetStatus and gRPC health latency (another client's) while `clients`
// clients create sessions on a labelled volume at once.
int RunCallsBench(const CallsBenchOptions& options);

// "NVIDIA H100 80GB HBM3 (cuda)" or "cpu, 2 threads".
std::string DeviceDescription(const std::string& backend);

}  // namespace cinevol::bench
