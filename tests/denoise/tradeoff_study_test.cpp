// A tiny CPU run of the speed/accuracy study (docs/tradeoff.md): every
// scenario on the head phantom at 96x64, every denoiser. It guards the
// study's numbers (nothing NaN) and wRLS's standing: well above the noisy
// input everywhere, steadier than SVGF on every still view, and not behind
// SVGF on the camera orbit.
#include "tradeoff_study.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>

#include "core/error.h"
#include "core/tone_map.h"
#include "encode/hdr_images.h"
#include "image_metrics.h"
#include "support/test_paths.h"
#include "support/time_series_nifti.h"

namespace cinevol::bench {
namespace {

TEST(TradeoffStudy, VariantsParseTheirKeysAndNameBadOnes) {
  const StudyConfig c = Variant("s8:spp=8,rescale=3,alpha=0.5");
  EXPECT_EQ(c.Label(), "wrls[s8]");
  EXPECT_EQ(c.spp, 8);
  EXPECT_EQ(c.wrls.feature_rescale, 3);
  EXPECT_FLOAT_EQ(c.wrls.alpha, 0.5f);
  EXPECT_EQ(Variant("d:method=svgf,sigma_depth=8,spp=4").method, DenoiseMethod::kSvgf);
  const StudyConfig plain = Variant("p:method=svgf,hold=0"), still = Variant("s:stabilize_still=0");
  EXPECT_FALSE(plain.hold_codes);
  EXPECT_TRUE(still.hold_codes);
  EXPECT_EQ(still.wrls.stabilize_still_frames, 0);
  EXPECT_THROW(Variant("h:hold=0.5"), InputError);
  EXPECT_TRUE(Variant("q:squared=1").wrls.atrous_squared_luminance);
  EXPECT_TRUE(Variant("q:method=svgf,squared=1").svgf.squared_luminance);
  EXPECT_THROW(Variant("q:squared=2"), InputError);
  EXPECT_TRUE(Variant("m:recenter_unmoved=1").wrls.stabilize_recenter_unmoved);
  EXPECT_THROW(Variant("m:recenter_unmoved=2"), InputError);
  EXPECT_THROW(Variant("s:stabilize_still=-1"), InputError);
  EXPECT_THROW(Variant("s:stabilize_still=1e10"), InputError) << "beyond an int";
  EXPECT_THROW(Variant("a:atrous=40"), InputError) << "a step of 2^39 pixels";
  EXPECT_EQ(Variant("n:normal_stop=1000").wrls.atrous_normal_stop, 1000.0f);
  EXPECT_THROW(Variant("n:normal_stop=1e30"), InputError) << "the centre tap's rounding would weigh 0";
  EXPECT_THROW(Variant("n:method=svgf,normal_stop=-1"), InputError);
  EXPECT_THROW(Variant("n:normal_share=0"), InputError);
  EXPECT_THROW(Variant("z:spp=0"), InputError);
  EXPECT_THROW(Variant("u:no_such_key=1"), InputError);
  EXPECT_THROW(Variant("n:alpha=abc"), InputError);
  EXPECT_THROW(Variant("n:alpha=nan"), InputError);
  EXPECT_THROW(Variant("n:alpha=0.5x"), InputError);
  EXPECT_THROW(Variant("k:method=knn"), InputError);
  EXPECT_THROW(Variant("r:rescale=0"), InputError) << "the study settled rescaling: it cannot be turned off";
  EXPECT_THROW(Variant("b:radius=2"), InputError) << "the paper's spatial blend left the code";
}

// A reference of few samples carries noise of its own, which adds to every
// image's squared error against it. Its two halves (independent seeds) tell
// how much: taken out, the PSNR is the one against the noise-free image.
TEST(TradeoffStudy, CorrectedPsnrTakesTheReferencesNoiseOut) {
  const int w = 256, h = 256, half_spp = 64;
  std::mt19937 rng(11);
  std::normal_distribution<float> unit;
  ImageRgbF truth{w, h, std::vector<Vec3f>(std::size_t(w) * h)}, image = truth;
  ReferenceHalves halves{truth, truth, half_spp, half_spp};
  for (std::size_t i = 0; i < truth.pixels.size(); ++i) {
    const float level = 0.05f + 1.5f * float(i % w) / float(w);
    truth.pixels[i] = {level, 0.8f * level, 0.6f * level};
    // A denoised image's error, and each half's noise at about the same size.
    for (int c = 0; c < 3; ++c) {
      image.pixels[i][c] = std::max(truth.pixels[i][c] + 0.02f * unit(rng), 0.0f);
      halves.a.pixels[i][c] = std::max(truth.pixels[i][c] + 0.02f * unit(rng), 0.0f);
      halves.b.pixels[i][c] = std::max(truth.pixels[i][c] + 0.02f * unit(rng), 0.0f);
    }
  }
  const ImageRgb8 shown = ToneMap(image, 0), reference = ToneMap(halves.Mean(), 0);
  const double exact = Psnr(shown, ToneMap(truth, 0)), plain = Psnr(shown, reference);
  const double corrected = CorrectedPsnr(shown, reference, ReferenceNoise(halves.a, halves.b, half_spp, half_spp, 0));
  EXPECT_LT(plain, exact - 1.0) << "the reference's noise should show here";
  EXPECT_NEAR(corrected, exact, 0.15);
  EXPECT_EQ(CorrectedPsnr(shown, shown, 0.0), 100.0);
}

// A cached reference of another size than the study's (an edited cache) is
// refused with its path, not compared pixel by pixel with frames it does not match.
TEST(TradeoffStudy, RefusesACachedReferenceOfAnotherSize) {
  testing::ScratchDir scratch;
  StudyOptions o;
  o.datasets = {{"phantom", std::string(CINEVOL_SOURCE_DIR) + "/examples/ct-bone.json", "phantom:head?size=16"}};
  o.scenarios = {"static"};
  o.width = 16;
  o.height = 12;
  o.frames_scale = 0.05f;
  o.reference_spp = 2;
  o.backend = "cpu";
  o.cache = scratch / "cache";
  o.configs = {StudyConfig{}};
  RunStudy(o);
  int replaced = 0;
  for (const auto& entry : std::filesystem::directory_iterator(o.cache)) {
    WriteExr(entry.path(), ImageRgbF{8, 8, std::vector<Vec3f>(64)});
    ++replaced;
  }
  ASSERT_EQ(replaced, 2) << "one still reference, in two halves";
  try {
    RunStudy(o);
    FAIL() << "a reference of another size was used";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("8x8, not the study's 16x12"), std::string::npos) << e.what();
  }
}

TEST(TradeoffStudy, TinyRunKeepsWrlsAheadAndNumbersFinite) {
  testing::ScratchDir scratch;
  StudyOptions o;
  o.datasets = {{"phantom", std::string(CINEVOL_SOURCE_DIR) + "/examples/ct-bone.json", "phantom:head?size=64"}};
  o.width = 96;
  o.height = 64;
  o.frames_scale = 0.3f;
  o.reference_spp = 128;
  o.backend = "cpu";
  o.cache = scratch / "cache";
  o.out = scratch / "out";
  o.configs = StudyConfigs(/*quick=*/true);
  const std::vector<RunResult> results = RunStudy(o);
  ASSERT_EQ(results.size(), (ScenarioNames().size() - 1) * o.configs.size()) << "all but beat: a still volume";

  std::map<std::string, std::map<std::string, double>> psnr, flicker;  // scenario -> config -> mean
  for (const RunResult& r : results) {
    ASSERT_TRUE(std::isfinite(r.flicker)) << r.scenario << " " << r.config.Label();
    flicker[r.scenario][r.config.Label()] = r.flicker;
    for (const FrameResult& f : r.frames) {
      for (double v : {f.psnr, f.psnr_corrected, f.ssim, f.rel_mse, f.temporal, f.render_ms, f.denoise_ms, f.tonemap_ms,
                       f.encode_ms}) {
        ASSERT_TRUE(std::isfinite(v)) << r.scenario << " " << r.config.Label() << " frame " << f.frame;
      }
    }
    psnr[r.scenario][r.config.Label()] = r.Mean(&FrameResult::psnr);
  }
  for (const auto& [scenario, by_config] : psnr) {
    EXPECT_GT(by_config.at("wrls"), by_config.at("none") + 3.0) << scenario;
    // wRLS's point is a steady picture (issue 38 asks a third of SVGF's
    // flicker at 720p; at this size it is 0.31-0.41).
    EXPECT_LT(flicker[scenario]["wrls"], 0.5 * flicker[scenario]["svgf"]) << scenario;
  }
  EXPECT_GE(psnr["orbit"]["wrls"], psnr["orbit"]["svgf"]) << "wRLS fell behind SVGF on the camera orbit";
  EXPECT_GT(psnr["static"]["wrls"], psnr["static"]["svgf"]) << "a still view should converge";
  EXPECT_TRUE(std::filesystem::exists(o.out / "tradeoff.csv"));
  EXPECT_TRUE(std::filesystem::exists(o.out / "tradeoff.json"));
  EXPECT_TRUE(std::filesystem::exists(o.out / "images" / "phantom" / "orbit" / "reference.jpg"));

  // A still view's references are one image, rendered once (in two halves):
  // their own noise would otherwise count as the denoisers' temporal error.
  int still_references = 0, orbit_references = 0;
  for (const auto& entry : std::filesystem::directory_iterator(o.cache)) {
    const std::string name = entry.path().filename().string();
    still_references += name.rfind("phantom-static-", 0) == 0;
    orbit_references += name.rfind("phantom-orbit-", 0) == 0;
  }
  EXPECT_EQ(still_references, 2);
  EXPECT_GT(orbit_references, 1);
}

// The beat scenario on a time series (a sphere moving a voxel a phase, the
// view still): each phase-history rule of wRLS measured against per-phase
// references. The history kept as though nothing changed smears the sphere
// across its switches; dropping it (the default) smears least.
TEST(TradeoffStudy, ABeatMeasuresEachPhaseHistoryRule) {
  testing::ScratchDir scratch;
  testing::WriteMovingSphere(scratch / "beat.nii", {.size = 32, .phases = 4, .radius = 8, .first_x = 10});
  StudyOptions o;
  o.datasets = {
      {"sphere", std::string(CINEVOL_SOURCE_DIR) + "/examples/ct-bone.json", (scratch / "beat.nii").string()}};
  o.scenarios = {"beat"};
  o.width = 96;
  o.height = 64;
  o.frames_scale = 0.5f;  // 20 frames: 5 phase switches
  o.reference_spp = 128;
  o.backend = "cpu";
  o.cache = scratch / "cache";
  o.configs = {Variant("changed:phase_history=changed"), Variant("reset:phase_history=reset"),
               Variant("kept:phase_history=kept")};
  EXPECT_EQ(o.configs[2].phase_history, PhaseHistory::kKept);
  EXPECT_EQ(StudyConfig{}.phase_history, PhaseHistory::kReset) << "the default";
  EXPECT_THROW(Variant("x:phase_history=sometimes"), InputError);
  const std::vector<RunResult> results = RunStudy(o);
  ASSERT_EQ(results.size(), 3u);
  std::map<std::string, double> psnr;
  for (const RunResult& r : results) {
    EXPECT_EQ(r.scenario, "beat");
    for (const FrameResult& f : r.frames) ASSERT_TRUE(std::isfinite(f.psnr) && std::isfinite(f.temporal));
    psnr[r.config.variant] = r.Mean(&FrameResult::psnr);
  }
  EXPECT_GT(psnr["changed"], psnr["kept"]) << "the sphere's old place should not linger";
  EXPECT_GT(psnr["reset"], psnr["changed"]) << "nor be reprojected onto the new phase";
}

}  // namespace
}  // namespace cinevol::bench
