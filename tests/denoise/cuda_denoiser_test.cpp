// CUDA denoisers against the CPU ones on the same rendered frames (GPU
// machine; skips elsewhere): every method, wRLS with demodulation too, and
// SVGF and wRLS with the squared luminance stop, wRLS with it calibrated.
#include <gtest/gtest.h>

#include <cmath>

#include "image_metrics.h"
#include "denoise/denoiser.h"
#include "io/phantom.h"
#include "render/renderer.h"
#include "support/gpu.h"

namespace cinevol {
namespace {

struct Case {
  DenoiseMethod method;
  bool demodulate;
  bool squared_stop = false;  // SvgfSettings::squared_luminance, WrlsSettings::atrous_squared_luminance
  float calibration_floor = 0.0f;  // WrlsSettings::atrous_calibration_floor
};

std::string CaseName(const Case& c) {
  return std::string(ToString(c.method)) + (c.demodulate ? "Demodulated" : "") + (c.squared_stop ? "SquaredStop" : "") +
         (c.calibration_floor > 0.0f ? "Calibrated" : "");
}

void PrintTo(const Case& c, std::ostream* os) { *os << CaseName(c); }

class CudaDenoiser : public ::testing::TestWithParam<Case> {};

TEST_P(CudaDenoiser, AgreesWithCpu) {
  CINEVOL_REQUIRE_CUDA();
  v1::Phantom p;
  p.set_kind(v1::Phantom::HEAD);
  p.set_size(64);
  p.set_spacing(4.0f);
  auto volume = std::make_shared<const Volume>(MakePhantom(p));
  TransferFunction tf;
  tf.points = {{-100, 0, {0.9f, 0.6f, 0.5f}, {}, 0.5f, {}}, {300, 1, {0.9f, 0.9f, 0.8f}, {0.2f, 0.2f, 0.2f}, 0.4f, {}}};
  tf.density_scale = 0.3f;
  LightSetup lights;
  lights.environment.kind = Environment::Kind::kUniform;
  lights.environment.zenith = {0.8f, 0.8f, 0.8f};
  auto renderer = CreateRenderer(Backend::kCuda);
  renderer->SetVolume(volume);
  renderer->SetTransferFunction(tf);
  renderer->SetLights(lights);

  DenoiserSettings s;
  s.method = GetParam().method;
  s.demodulate = GetParam().demodulate;
  s.svgf.squared_luminance = s.wrls.atrous_squared_luminance = GetParam().squared_stop;
  s.wrls.atrous_calibration_floor = GetParam().calibration_floor;
  auto gpu = CreateDenoiser(Backend::kCuda, s), cpu = CreateDenoiser(Backend::kCpu, s);
  // Wider than a GPU row segment (RowWindowSums), so windows cross one.
  const int w = 272, h = 32;
  // An orbit that pauses every other frame, told each frame that only the
  // camera moved: wRLS recentres where pixels moved and not where they stayed.
  for (int t = 0; t < 12; ++t) {
    FrameRequest req;
    const float angle = 0.05f * float(t / 2);
    req.camera =
        LookAt({400.0f * std::cos(angle), -400.0f * std::sin(angle + 1.5f), 50}, {0, 0, 0}, {0, 0, 1}, 32, w, h);
    req.spp = 2;
    req.frame = t;
    renderer->Render(req);
    const FrameTargets device = renderer->Targets();
    gpu->Denoise({w, h, device.radiance, device.first_hit, device.albedo, req.camera, true, true});
    const ImageRgbF radiance = renderer->Radiance(), albedo = renderer->Albedo();
    const std::vector<Vec4f> hits = renderer->FirstHits();
    cpu->Denoise({w, h, radiance.pixels.data(), hits.data(), albedo.pixels.data(), req.camera, true, true});
    const ImageRgbF a = gpu->Output(), b = cpu->Output();
    int differing = 0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i) {
      ASSERT_TRUE(IsFinite(a.pixels[i]));
      const float d = MaxComponent(Abs(a.pixels[i] - b.pixels[i]));
      differing += d > 1e-3f * std::max(1.0f, MaxComponent(b.pixels[i]));
    }
    EXPECT_LE(differing, int(a.pixels.size() / 100)) << "frame " << t;
    EXPECT_GT(DisplayPsnr(a, b), 50.0) << "frame " << t;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Methods, CudaDenoiser,
    ::testing::Values(Case{DenoiseMethod::kNone, false}, Case{DenoiseMethod::kAccumulate, false},
                      Case{DenoiseMethod::kKnn, false}, Case{DenoiseMethod::kGuidedFilter, false},
                      Case{DenoiseMethod::kSvgf, false}, Case{DenoiseMethod::kWrls, false},
                      Case{DenoiseMethod::kWrls, true}, Case{DenoiseMethod::kSvgf, false, true},
                      Case{DenoiseMethod::kWrls, false, true}, Case{DenoiseMethod::kWrls, false, true, 0.0625f}),
    [](const auto& info) { return CaseName(info.param); });

}  // namespace
}  // namespace cinevol
