// cinevol-bench scale: how a CT's cost grows with its slices. A shared CT is
// resampled (trilinear) to 512x512 pixels over its field of view and N slices
// 0.8 mm apart (its anatomy stretched along z into a longer scan's worth of
// voxels), written as a raw 16-bit NRRD, and met as a session meets it: read
// through the reader cage, prepared (brick ranges), uploaded, the first 720p
// frame, then frames; with the memory it takes on the host and the device.
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "bench.h"
#include "device/device.h"
#include "io/volume_loader.h"
#include "pipeline/frame_pipeline.h"
#include "render/prepared_volume.h"
#include "resampled_volume.h"
#include "scene/presets.h"
#include "scene/scene_file.h"

namespace cinevol::bench {
namespace {

namespace fs = std::filesystem;

template <class F>
double Milliseconds(F&& f) {
  const auto start = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

double MiB(double bytes) { return bytes / double(1 << 20); }

double FreeGpuMiB() { return MiB(double(ListGpus().at(0).free_bytes)); }

struct Row {
  Vec3i dims;
  double read_ms, prepare_ms, upload_ms, first_frame_ms, frame_ms;
  double host_mib, voxels_mib, majorants_mib, session_mib;
};

Row Measure(const ScaleBenchOptions& o, const fs::path& file, Vec3i dims) {
  Row r{};
  r.dims = dims;
  std::shared_ptr<const Volume> volume;
  r.read_ms = Milliseconds([&] { volume = std::make_shared<const Volume>(LoadVolume(ParseVolumeSpec(file.string()))); });
  std::shared_ptr<const VolumeCopy> host, gpu;
  r.prepare_ms = Milliseconds([&] { host = VolumeCache::Get().Acquire(volume, kDefaultBrickSize, kHostDevice); });
  r.host_mib = MiB(double(volume->MemoryBytes() + host->prepared().host_bytes()));
  r.upload_ms = Milliseconds([&] { gpu = VolumeCache::Get().Acquire(volume, kDefaultBrickSize, 0); });
  r.voxels_mib = MiB(double(gpu->bytes()));

  v1::Scene scene = MakePresetScene(DefaultPreset(*volume), *volume);
  scene.mutable_render()->set_width(1280);
  scene.mutable_render()->set_height(720);
  ApplyDefaults(scene);
  const double free_before = FreeGpuMiB();
  std::unique_ptr<FramePipeline> pipeline;
  r.first_frame_ms = Milliseconds([&] {
    pipeline = std::make_unique<FramePipeline>(Backend::kCuda, volume);
    pipeline->Update(scene, FrameSettings{});
    pipeline->RenderFrame();
  });
  r.session_mib = free_before - FreeGpuMiB();
  std::vector<double> ms;
  for (int f = 0; f < o.frames; ++f) ms.push_back(pipeline->RenderFrame().render_ms);
  std::sort(ms.begin(), ms.end());
  r.frame_ms = ms.empty() ? 0 : ms[ms.size() / 2];
  const BrickRanges& bricks = host->prepared().brick_ranges(Reconstruction::kTrilinear);
  r.majorants_mib = MiB(double(bricks.min.size()) * sizeof(float));
  return r;
}

}  // namespace

int RunScaleBench(const ScaleBenchOptions& o) {
  if (ListGpus().empty()) throw std::runtime_error("cinevol-bench scale needs a GPU");
  const Volume source = LoadVolume(ParseVolumeSpec(o.volume));
  const fs::path scratch = o.scratch.empty() ? fs::temp_directory_path() / "cinevol-scale" : fs::path(o.scratch);
  fs::create_directories(scratch);
  const Vec3f box = source.spacing_mm() * ToFloat(source.dims());
  std::string table = fmt::format(
      "\n`{}` ({}; {} resampled to {}x{} over its {:.0f}x{:.0f} mm field of view, slices {} mm apart)\n\n"
      "| voxels | read ms | prepare ms | upload ms | first frame ms | frame ms (median of {}) | host MiB | "
      "device: voxels MiB | majorants MiB | a session's pipeline MiB |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n",
      o.command_line, DeviceDescription("cuda"), o.volume, o.pixels, o.pixels, box.x, box.y, o.slice_mm, o.frames);
  std::vector<Row> rows;
  for (const int slices : o.slices) {
    const Vec3i dims{o.pixels, o.pixels, slices};
    const fs::path file = scratch / fmt::format("ct-{}x{}x{}.nrrd", dims.x, dims.y, dims.z);
    WriteNrrd(file, dims, {box.x / float(dims.x), box.y / float(dims.y), o.slice_mm}, Resample(source, dims), source);
    const Row r = Measure(o, file, dims);
    fs::remove(file);
    rows.push_back(r);
    table += fmt::format("| {}x{}x{} | {:.0f} | {:.0f} | {:.0f} | {:.0f} | {:.3f} | {:.0f} | {:.0f} | {:.1f} | {:.0f} |\n",
                         r.dims.x, r.dims.y, r.dims.z, r.read_ms, r.prepare_ms, r.upload_ms, r.first_frame_ms,
                         r.frame_ms, r.host_mib, r.voxels_mib, r.majorants_mib, r.session_mib);
  }
  // What the GPU holds beside `sessions` 720p sessions, by the largest row's
  // device bytes a voxel (voxels and one set of majorants).
  const Row& big = rows.back();
  const double voxels = double(big.dims.x) * big.dims.y * big.dims.z;
  const double bytes_per_voxel = (big.voxels_mib + big.majorants_mib) * double(1 << 20) / voxels;
  const double total = MiB(double(ListGpus().at(0).total_bytes));
  const double room = total - double(o.sessions) * big.session_mib;
  table += fmt::format(
      "\nBeside {} sessions of {:.0f} MiB each, the GPU's {:.0f} MiB leave room for a volume of about {:.2g} "
      "voxels ({:.2f} bytes a voxel on the device: voxels and one set of majorants), e.g. 512x512x{:.0f}; "
      "the server's cap is 2^30 voxels a volume (512x512x4096).\n",
      o.sessions, big.session_mib, total, room * double(1 << 20) / bytes_per_voxel, bytes_per_voxel,
      room * double(1 << 20) / bytes_per_voxel / (512.0 * 512.0));
  SceneOptions report;
  report.out = o.out;
  Report(report, table);
  return 0;
}

}  // namespace cinevol::bench
