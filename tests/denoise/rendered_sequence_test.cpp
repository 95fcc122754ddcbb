// The evidence on a real rendered sequence (CPU): a camera orbiting the head
// phantom at 2 spp per frame, against a 128-spp render of every frame.
// wRLS must beat the noisy input by a clear PSNR margin, beat
// accumulation-with-reset while the camera moves, and keep the image's level.
#include <gtest/gtest.h>

#include <cmath>

#include "image_metrics.h"
#include "denoise/denoiser.h"
#include "io/phantom.h"
#include "render/cpu_renderer.h"

namespace cinevol {
namespace {

struct OrbitScene {
  std::shared_ptr<const Volume> volume;
  TransferFunction tf;
  LightSetup lights;

  OrbitScene() {
    v1::Phantom p;
    p.set_kind(v1::Phantom::HEAD);
    p.set_size(64);
    p.set_spacing(4.0f);
    volume = std::make_shared<const Volume>(MakePhantom(p));
    tf.points = {{-300, 0, {0.9f, 0.6f, 0.5f}, {}, 0.5f, {}},
                 {-50, 0.05f, {0.9f, 0.6f, 0.5f}, {0.1f, 0.1f, 0.1f}, 0.5f, {}},
                 {60, 0.3f, {0.9f, 0.55f, 0.45f}, {0.1f, 0.1f, 0.1f}, 0.5f, {}},
                 {400, 1, {0.92f, 0.88f, 0.78f}, {0.2f, 0.2f, 0.2f}, 0.4f, {}}};
    tf.density_scale = 0.2f;
    tf.gradient_factor = 1.5f;
    lights.environment.kind = Environment::Kind::kUniform;
    lights.environment.zenith = {0.3f, 0.32f, 0.35f};
    Light key;
    key.kind = LightKind::kDirectional;
    key.direction = Normalize(Vec3f{0.6f, 0.7f, -0.5f});
    key.emitted = {2.5f, 2.4f, 2.2f};
    lights.lights = {key};
  }

  // Frame t of an orbit: 2 degrees per frame around the vertical axis.
  static Camera CameraAt(int t, int width, int height) {
    const float a = (200.0f + 2.0f * float(t)) * kPi / 180.0f;
    return LookAt({420.0f * std::cos(a), 420.0f * std::sin(a), 60.0f}, {0, 0, 0}, {0, 0, 1}, 32, width, height);
  }
};

TEST(RenderedSequence, WrlsBeatsNoiseAndAccumulationDuringMotion) {
  const int w = 48, h = 36, frames = 24, warmup = 8;
  const OrbitScene scene;
  CpuRenderer noisy, reference;
  for (CpuRenderer* r : {&noisy, &reference}) {
    r->SetVolume(scene.volume);
    r->SetTransferFunction(scene.tf);
    r->SetLights(scene.lights);
  }
  DenoiserSettings wrls_settings, accumulate_settings;
  wrls_settings.method = DenoiseMethod::kWrls;
  accumulate_settings.method = DenoiseMethod::kAccumulate;
  auto wrls = CreateDenoiser(Backend::kCpu, wrls_settings);
  auto accumulate = CreateDenoiser(Backend::kCpu, accumulate_settings);

  double psnr_noisy = 0, psnr_wrls = 0, psnr_accumulate = 0, level_wrls = 0;
  for (int t = 0; t < frames; ++t) {
    FrameRequest req;
    req.camera = OrbitScene::CameraAt(t, w, h);
    req.max_bounces = 4;
    req.frame = t;
    req.spp = 128;
    req.seed = 99;
    reference.Render(req);
    req.spp = 2;
    req.seed = 1;
    noisy.Render(req);
    const FrameTargets targets = noisy.Targets();
    DenoiseFrame f{w, h, targets.radiance, targets.first_hit, targets.albedo, req.camera, true};  // an orbit
    wrls->Denoise(f);
    accumulate->Denoise(f);
    if (t < warmup) continue;
    const ImageRgbF truth = reference.Radiance();
    psnr_noisy += DisplayPsnr(noisy.Radiance(), truth) / (frames - warmup);
    psnr_wrls += DisplayPsnr(wrls->Output(), truth) / (frames - warmup);
    psnr_accumulate += DisplayPsnr(accumulate->Output(), truth) / (frames - warmup);
    level_wrls += LevelBias(wrls->Output(), truth) / (frames - warmup);
  }
  RecordProperty("psnr_noisy", std::to_string(psnr_noisy));
  RecordProperty("psnr_wrls", std::to_string(psnr_wrls));
  std::printf("moving camera, mean PSNR over frames %d..%d: noisy %.2f dB, accumulation %.2f dB, wRLS %.2f dB "
              "(level %+.2f%%)\n",
              warmup, frames - 1, psnr_noisy, psnr_accumulate, psnr_wrls, 100 * level_wrls);
  EXPECT_GT(psnr_wrls, psnr_noisy + 3.0);
  EXPECT_GT(psnr_wrls, psnr_accumulate + 3.0);
  // The paper's sample weight (Eq. 13, dividing by min(|sample|, |z|)) leant
  // the level +2.6% bright here; the weight relative to the feature +0.05%.
  EXPECT_LT(std::abs(level_wrls), 0.01) << "wRLS's output is brighter or darker than the scene";
}

}  // namespace
}  // namespace cinevol
