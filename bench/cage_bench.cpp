// cinevol-bench cage: what the reader cage costs. Each volume is loaded the
// way a server loads it (a cinevol-reader child, the spare the server keeps
// ready, its sandbox, the header, the voxels through a memfd) and in this
// process with the same reader code and no child, alternately; the medians
// and the server-side peak memory per voxel go to docs/performance.md.
#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <thread>

#include "bench.h"
#include "io/file_checks.h"
#include "io/formats/format.h"
#include "io/reader_cage.h"
#include "io/readers/reading.h"
#include "io/volume_loader.h"

namespace fs = std::filesystem;

namespace cinevol::bench {
namespace {

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

// The resident memory's peak since the last reset (VmHWM), bytes.
std::uint64_t PeakResident() {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6)) << 10;
  }
  return 0;
}

std::uint64_t Resident() {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stoull(line.substr(6)) << 10;
  }
  return 0;
}

void ResetPeak() { std::ofstream("/proc/self/clear_refs") << "5"; }

// The request a cage load of `path` makes, and its inputs opened.
reader::Request RequestFor(const fs::path& path, std::vector<UniqueFd>& inputs, const fs::path& work_dir) {
  reader::Request request;
  request.set_shown(path.string());
  request.set_max_voxels(std::uint64_t{1} << 30);
  request.set_work_dir(work_dir.string());
  auto add = [&](const fs::path& file, const std::string& name) {
    inputs.emplace_back(file_checks::OpenRegularFile(file));
    request.add_file_names(name);
  };
  if (fs::is_directory(path)) {
    request.set_kind(reader::Request::DICOM_SERIES);
    std::vector<fs::path> files;
    for (const auto& e : fs::recursive_directory_iterator(path)) {
      if (e.is_regular_file()) files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());
    for (const fs::path& f : files) add(f, f.lexically_relative(path).string());
    return request;
  }
  request.set_kind(reader::Request::VOLUME);
  add(path, path.filename().string());
  for (const fs::path& named : formats::FindReferences(path, path.string()).files) {
    add(named, named.lexically_relative(path.parent_path()).string());
  }
  return request;
}

// A load in this process through the readers' own entry point.
Volume LoadInProcess(const fs::path& path) {
  char pattern[] = "/tmp/cinevol-bench-XXXXXX";
  const fs::path work_dir = mkdtemp(pattern);
  std::vector<UniqueFd> inputs;
  const reader::Request request = RequestFor(path, inputs, work_dir);
  auto* memory = new std::vector<unsigned char>;
  const reader::Reply reply = reader::ReadInProcess(request, std::move(inputs), *memory);
  fs::remove_all(work_dir);
  const reader::Header& h = reply.header();
  VolumeMetadata meta;
  meta.source = path.string();
  MemoryBlock block(memory->data(), memory->size(), MemoryBlock::Pages::kHeap,
                    [memory](void*, std::size_t) { delete memory; });
  return Volume({int(h.dims(0)), int(h.dims(1)), int(h.dims(2))},
                {float(h.spacing_mm(0)), float(h.spacing_mm(1)), float(h.spacing_mm(2))},
                *VoxelTypeNamed(h.voxel_type()), std::move(block), meta);
}

template <class F>
double Milliseconds(F&& f) {
  const auto start = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

std::string Row(const std::string& spec, int runs) {
  std::vector<double> inside, caged;
  double peak_per_voxel = 0;
  std::string type;
  Vec3i dims;
  for (int r = 0; r < runs; ++r) {
    inside.push_back(Milliseconds([&] { LoadInProcess(spec); }));
    const std::uint64_t before = Resident();
    ResetPeak();
    caged.push_back(Milliseconds([&] {
      const Volume v = LoadVolume(ParseVolumeSpec(spec));
      dims = v.dims();
      type = v.metadata().original_type;
      peak_per_voxel = double(PeakResident() - std::min(before, PeakResident())) / double(v.voxel_count());
    }));
    // The next spare reader starts once a load ends; loads that arrive apart
    // find it ready, and the load in this process does not share the processor with its start.
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
  }
  const double a = Median(inside), b = Median(caged);
  return fmt::format("| {} | {}x{}x{} | {} | {:.0f} | {:.0f} | {:+.0f} ({:+.0f}%) | {:.2f} |\n",
                     fs::path(spec).filename().string(), dims.x, dims.y, dims.z, type, a, b, b - a,
                     a > 0 ? 100 * (b - a) / a : 0.0, peak_per_voxel);
}

}  // namespace

int RunCageBench(const CageBenchOptions& options) {
  reader_cage::KeepSpareReader();  // as the server does
  std::string table = fmt::format(
      "\n`{}` ({}; medians of {} loads each, alternating)\n\n"
      "| volume | voxels | type in the file | in process ms | caged ms | cage's cost ms | server peak bytes/voxel "
      "(caged) |\n| --- | --- | --- | --- | --- | --- | --- |\n",
      options.command_line, DeviceDescription("cpu"), options.runs);
  for (const std::string& spec : options.volumes) table += Row(spec, options.runs);
  SceneOptions report;
  report.out = options.out;
  Report(report, table);
  return 0;
}

}  // namespace cinevol::bench
