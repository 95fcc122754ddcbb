// `cinevol-bench encode`: a streamed frame's JPEG made each way the server can
// make it, from the same rendered frames of a camera orbit: libjpeg-turbo on
// the CPU from the planes copied to the host (whole, and in the 4 bands a
// lone session gets), and on the GPU from the planes where they lie:
// cinevol's coder and nvJPEG (--jpeg-encoder). Per way: the display and encode
// times, the JPEG's size, and its decoded PSNR against the displayed image and
// against the CPU's JPEG of the same frame.
// Prints a Markdown table (and appends it to --out) for docs/performance.md.
#include <algorithm>
#include <chrono>
#include <vector>

#include <fmt/format.h>

#include "bench.h"
#include "image_metrics.h"
#include "pipeline/frame_pipeline.h"
#include "tradeoff_study.h"

namespace cinevol::bench {
namespace {

using Clock = std::chrono::steady_clock;

// Per frame of one way of encoding.
struct Samples {
  std::vector<double> display_ms, encode_ms, bytes, psnr_displayed, psnr_cpu;
};

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double Mean(const std::vector<double>& v) {
  double sum = 0;
  for (double x : v) sum += x;
  return v.empty() ? 0 : sum / double(v.size());
}

double TotalP90(const Samples& s) {
  std::vector<double> total;
  for (std::size_t i = 0; i < s.display_ms.size(); ++i) total.push_back(s.display_ms[i] + s.encode_ms[i]);
  std::sort(total.begin(), total.end());
  return total.empty() ? 0 : total[total.size() * 9 / 10];
}

// EncodeJpeg from host planes, timed.
std::vector<std::uint8_t> TimedCpuEncode(const DisplayFrame& frame, int bands, double& ms) {
  const auto start = Clock::now();
  std::vector<std::uint8_t> jpeg = EncodeJpeg(frame.image, frame.jpeg_quality, bands);
  ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  return jpeg;
}

void Add(Samples& s, double display_ms, double encode_ms, const std::vector<std::uint8_t>& jpeg,
         const ImageRgb8& displayed, const ImageRgb8& cpu_decoded) {
  const ImageRgb8 decoded = DecodeJpeg(jpeg);
  s.display_ms.push_back(display_ms);
  s.encode_ms.push_back(encode_ms);
  s.bytes.push_back(double(jpeg.size()));
  s.psnr_displayed.push_back(Psnr(decoded, displayed));
  s.psnr_cpu.push_back(Psnr(decoded, cpu_decoded));
}

std::string Row(const std::string& name, const Samples& s) {
  return fmt::format("| {} | {:.3f} | {:.3f} | {:.3f} | {:.3f} | {:.1f} | {:.2f} | {:.2f} |\n", name,
                     Median(s.display_ms), Median(s.encode_ms), Median(s.display_ms) + Median(s.encode_ms),
                     TotalP90(s), Mean(s.bytes) / 1024.0, Mean(s.psnr_displayed), Mean(s.psnr_cpu));
}

}  // namespace

namespace {

// The GPU encoders --jpeg-encoder asks for on `backend`: auto takes
// cinevol's coder on a GPU, and nvJPEG beside it where it loads.
std::vector<JpegEncoderKind> DeviceEncoders(const std::string& flag, Backend backend) {
  const JpegEncoderKind requested = ParseJpegEncoder(flag);
  if (requested != JpegEncoderKind::kAuto) {
    const JpegEncoderKind chosen = ChooseJpegEncoder(requested, backend);
    return chosen == JpegEncoderKind::kCpu ? std::vector<JpegEncoderKind>{} : std::vector{chosen};
  }
  std::vector<JpegEncoderKind> kinds;
  if (ChooseJpegEncoder(requested, backend) == JpegEncoderKind::kCuda) kinds.push_back(JpegEncoderKind::kCuda);
  if (backend == Backend::kCuda && ProcessNvjpeg().library) kinds.push_back(JpegEncoderKind::kNvjpeg);
  return kinds;
}

std::string DeviceEncoderName(JpegEncoderKind kind) {
  return kind == JpegEncoderKind::kCuda
             ? fmt::format("cuda: cinevol's coder, {}-block intervals", CudaJpegSettings{}.blocks_per_interval)
             : "nvjpeg: " + ProcessNvjpeg().library->name;
}

}  // namespace

int RunEncodeBench(const EncodeBenchOptions& o) {
  const LoadedScene loaded = LoadScene(o);
  const Backend backend = Resolve(ParseBackend(o.backend), "--backend");
  const std::vector<JpegEncoderKind> device_kinds = DeviceEncoders(o.jpeg_encoder, backend);
  FrameSettings settings;
  settings.jpeg_quality = o.quality;
  settings.refine = false;  // frames as they look while the view moves, every one displayed anew
  FramePipeline cpu(backend, loaded.volume, {}, loaded.labels);
  std::vector<std::unique_ptr<FramePipeline>> devices;
  for (JpegEncoderKind kind : device_kinds) {
    devices.push_back(std::make_unique<FramePipeline>(backend, loaded.volume, RendererOptions{}, loaded.labels));
    devices.back()->SetJpegEncoder(kind);
  }
  Samples whole, banded;
  std::vector<Samples> on_device(devices.size());
  RenderSetup view = loaded.setup;
  for (int f = 0; f < o.warmup + o.frames; ++f) {
    view.camera = Orbit(loaded.setup.camera, float(f) * o.degrees_per_frame);
    const unsigned changes = f == 0 ? kEverythingChanged : kCameraChanged;
    cpu.Update(view, settings, changes);
    const DisplayFrame planes = cpu.RenderFrame();
    double whole_ms = 0, banded_ms = 0;
    const std::vector<std::uint8_t> cpu_jpeg = TimedCpuEncode(planes, 1, whole_ms);
    const std::vector<std::uint8_t> banded_jpeg = TimedCpuEncode(planes, 4, banded_ms);
    std::vector<DisplayFrame> encoded;
    for (auto& device : devices) {
      device->Update(view, settings, changes);
      encoded.push_back(device->RenderFrame());
    }
    if (f < o.warmup) continue;
    const ImageRgb8 displayed = ToRgb(planes.image);
    const ImageRgb8 cpu_decoded = DecodeJpeg(cpu_jpeg);
    Add(whole, planes.display_ms, whole_ms, cpu_jpeg, displayed, cpu_decoded);
    Add(banded, planes.display_ms, banded_ms, banded_jpeg, displayed, cpu_decoded);
    for (std::size_t d = 0; d < devices.size(); ++d) {
      Add(on_device[d], encoded[d].display_ms, encoded[d].encode_ms, encoded[d].jpeg.bytes, displayed, cpu_decoded);
    }
  }

  const RenderSetup& setup = loaded.setup;
  std::string table = fmt::format(
      "\n### JPEG encoders: {} on {}\n\n`{}`\n\n{}x{}, quality {}, 4:2:0, {} spp, the camera orbiting {} degrees a frame; "
      "median of {} frames after {} warm-up (PSNR and size: means). Display: tone map and YCbCr planes, and for the "
      "CPU encoder their copy to the host; encode: from the planes to the JPEG's bytes on the host.\n\n"
      "| encoder | display ms | encode ms | display + encode ms | p90 ms | JPEG KiB | PSNR vs displayed dB | "
      "PSNR vs CPU JPEG dB |\n|---|---|---|---|---|---|---|---|\n",
      o.scene, DeviceDescription(o.backend), o.command_line, setup.camera.width, setup.camera.height, o.quality,
      setup.spp, o.degrees_per_frame, o.frames, o.warmup);
  table += Row("cpu: libjpeg-turbo, whole", whole);
  table += Row("cpu: libjpeg-turbo, 4 bands", banded);
  for (std::size_t d = 0; d < devices.size(); ++d) table += Row(DeviceEncoderName(device_kinds[d]), on_device[d]);
  if (devices.empty()) table += fmt::format("\nNo GPU encoder measured: --jpeg-encoder {}.\n", o.jpeg_encoder);
  Report(o, table);
  return 0;
}

}  // namespace cinevol::bench
