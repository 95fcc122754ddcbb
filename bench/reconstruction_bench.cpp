// `cinevol-bench reconstruction`: what tricubic reconstruction buys on
// coarse data. A ball of 1000 in 0 (partial-volume voxelised, as a scanner's
// voxels average what they cover) at coarse spacings is rendered with each
// reconstruction and compared with the same ball at a fine spacing: PSNR and
// SSIM of the displayed image where the reference sees the surface, and the
// milliseconds of a 720p frame at 2 spp.
#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "bench.h"
#include "image_metrics.h"
#include "core/tone_map.h"
#include "encode/image_codecs.h"
#include "io/phantom.h"
#include "scene/presets.h"
#include "scene/scene_file.h"
#include "pipeline/frame_pipeline.h"

namespace cinevol::bench {
namespace {

constexpr float kExtentMm = 90.0f, kRadiusMm = 30.0f;

std::shared_ptr<const Volume> Ball(float spacing) {
  v1::Phantom p;
  p.set_kind(v1::Phantom::SPHERE);
  p.set_size(static_cast<std::uint32_t>(std::lround(kExtentMm / spacing)));
  p.set_spacing(spacing);
  p.set_value(1000);
  p.set_background(0);
  p.set_radius(kRadiusMm);
  return std::make_shared<const Volume>(MakePhantom(p));
}

// An opaque surface at the half value under a narrow ramp, lit by the
// preset scenes' key light and sky; one fixed camera for every volume.
v1::Scene BallScene(const Volume& volume, int width, int height, int spp, v1::Reconstruction r) {
  v1::Scene scene = MakePresetScene("ct-bone", volume);
  v1::TransferFunction* tf = scene.mutable_transfer_function();
  tf->clear_preset();
  for (auto [value, opacity] : {std::pair{0.0f, 0.0f}, {450.0f, 0.0f}, {550.0f, 1.0f}, {1000.0f, 1.0f}}) {
    v1::TransferFunctionPoint* point = tf->add_points();
    point->set_value(value);
    point->set_opacity(opacity);
    point->mutable_diffuse()->set_r(0.9f);
    point->mutable_diffuse()->set_g(0.75f);
    point->mutable_diffuse()->set_b(0.65f);
    point->set_roughness(0.6f);
  }
  tf->set_density_scale(10.0f);
  tf->set_gradient_factor(5.0f);
  v1::Camera* camera = scene.mutable_camera();
  camera->set_view(v1::NAMED_VIEW_UNSPECIFIED);
  auto set = [](v1::Vec3* v, float x, float y, float z) {
    v->set_x(x);
    v->set_y(y);
    v->set_z(z);
  };
  set(camera->mutable_eye(), 60, -170, 70);
  set(camera->mutable_target(), 0, 0, 0);
  set(camera->mutable_up(), 0, 0, 1);
  scene.mutable_render()->set_width(width);
  scene.mutable_render()->set_height(height);
  scene.mutable_render()->set_spp(spp);
  scene.mutable_render()->set_reconstruction(r);
  ApplyDefaults(scene);
  return scene;
}

ImageRgbF Render(const ReconstructionBenchOptions& o, const std::shared_ptr<const Volume>& volume,
                 v1::Reconstruction r, int spp) {
  FramePipeline pipeline(ParseBackend(o.backend), volume);
  FrameSettings settings;
  settings.denoiser.method = DenoiseMethod::kNone;
  pipeline.Update(BallScene(*volume, o.width, o.height, std::min(spp, 64), r), settings);
  pipeline.Accumulate(spp);
  return pipeline.AccumulatedRadiance();
}

double FrameMs(const ReconstructionBenchOptions& o, const std::shared_ptr<const Volume>& volume, v1::Reconstruction r) {
  FramePipeline pipeline(ParseBackend(o.backend), volume);
  FrameSettings settings;
  settings.denoiser.method = DenoiseMethod::kNone;
  pipeline.Update(BallScene(*volume, 1280, 720, 2, r), settings);
  std::vector<double> ms;
  for (int f = 0; f < o.warmup + o.frames; ++f) {
    const double t = pipeline.RenderFrame().render_ms;
    if (f >= o.warmup) ms.push_back(t);
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

void WritePng(const ImageRgb8& image, const std::string& path) { WriteFile(path, EncodePng(image)); }

ImageRgb8 Crop(const ImageRgb8& image, int x0, int y0, int x1, int y1) {
  ImageRgb8 out{x1 - x0, y1 - y0, std::vector<std::uint8_t>(std::size_t(x1 - x0) * (y1 - y0) * 3)};
  for (int y = y0; y < y1; ++y) {
    std::copy_n(&image.bytes[(std::size_t(y) * image.width + x0) * 3], std::size_t(x1 - x0) * 3,
                &out.bytes[(std::size_t(y - y0) * out.width) * 3]);
  }
  return out;
}

}  // namespace

int RunReconstructionBench(const ReconstructionBenchOptions& o) {
  const std::string device = DeviceDescription(o.backend);
  const auto reference_volume = Ball(o.reference_spacing);
  // Tricubic: at 0.25 mm trilinear's per-cell gradients still show as rings.
  const ImageRgb8 reference = ToneMap(Render(o, reference_volume, v1::TRICUBIC, o.spp), 0.0f);
  // The ball's bounding rectangle in the reference, where PSNR and SSIM are taken.
  int x0 = reference.width, y0 = reference.height, x1 = 0, y1 = 0;
  const std::uint8_t* corner = reference.bytes.data();
  for (int y = 0; y < reference.height; ++y) {
    for (int x = 0; x < reference.width; ++x) {
      const std::uint8_t* p = &reference.bytes[(std::size_t(y) * reference.width + x) * 3];
      if (std::abs(int(p[0]) - corner[0]) + std::abs(int(p[1]) - corner[1]) + std::abs(int(p[2]) - corner[2]) > 6) {
        x0 = std::min(x0, x);
        y0 = std::min(y0, y);
        x1 = std::max(x1, x + 1);
        y1 = std::max(y1, y + 1);
      }
    }
  }
  if (x1 <= x0) throw std::runtime_error("the reference shows no ball");
  const ImageRgb8 reference_crop = Crop(reference, x0, y0, x1, y1);
  if (!o.images.empty()) {
    std::filesystem::create_directories(o.images);
    WritePng(reference, o.images + fmt::format("/ball-{}mm.png", o.reference_spacing));
  }
  std::string table = fmt::format(
      "\n### Reconstruction on {}\n\n`{}`\n\nA ball of radius {} mm (1000 in 0, partial-volume voxelised) in a {} mm "
      "box, opaque surface at 500 (ramp 450..550), {}x{} at {} spp against the ball at {} mm (tricubic); PSNR and SSIM "
      "of the "
      "displayed image over the ball's bounding rectangle ({}x{}); ms: median 720p frame at 2 spp\n\n"
      "| spacing | reconstruction | PSNR dB | SSIM | ms/frame 720p 2 spp |\n|---|---|---|---|---|\n",
      device, o.command_line, kRadiusMm, kExtentMm, o.width, o.height, o.spp, o.reference_spacing, x1 - x0, y1 - y0);
  for (float spacing : o.spacings) {
    const auto volume = Ball(spacing);
    for (v1::Reconstruction r : {v1::TRILINEAR, v1::TRICUBIC}) {
      const ImageRgb8 image = ToneMap(Render(o, volume, r, o.spp), 0.0f);
      const ImageRgb8 crop = Crop(image, x0, y0, x1, y1);
      const char* name = r == v1::TRILINEAR ? "trilinear" : "tricubic";
      table += fmt::format("| {} mm | {} | {:.2f} | {:.4f} | {:.3f} |\n", spacing, name, Psnr(crop, reference_crop),
                           Ssim(crop, reference_crop), FrameMs(o, volume, r));
      if (!o.images.empty()) WritePng(image, o.images + fmt::format("/ball-{}mm-{}.png", spacing, name));
    }
  }
  Report(o, table);
  return 0;
}

}  // namespace cinevol::bench
