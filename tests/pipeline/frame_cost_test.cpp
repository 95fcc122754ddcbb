// The CPU's choice of moving and still frames from measured costs
// (pipeline/frame_cost.h).
#include <gtest/gtest.h>

#include "pipeline/frame_cost.h"

namespace cinevol {
namespace {

constexpr std::int64_t k720p = 1280 * 720;

// A full-size frame of 2 spp at 720p as a 2-core CPU renders it: 600 ms of
// render, 300 of denoising, 20 of display, 300 of refinement, nothing else.
FrameCostModel Measured720p() {
  FrameCostModel model;
  model.Observe({k720p, k720p, 2, 600, 300, 20, 300, 1220});
  return model;
}

TEST(FrameCostModel, PredictsEverySizeFromOneFrame) {
  const FrameCostModel model = Measured720p();
  EXPECT_NEAR(model.PredictMoving(k720p, 2, k720p), 600 + 300 + 20, 1e-6) << "no refinement while moving";
  EXPECT_NEAR(model.PredictMoving(k720p / 16, 1, k720p), 600.0 / 32 + 300.0 / 16 + 20, 1e-6)
      << "render per pixel and sample, denoise per pixel, display per pixel displayed";
  EXPECT_NEAR(model.PredictMoving(k720p / 16, 1, k720p / 16), 600.0 / 32 + 300.0 / 16 + 20.0 / 16, 1e-6)
      << "a frame that leaves at its rendered size displays its own pixels";
  EXPECT_NEAR(model.StillOverhead(k720p), 300 + 20 + 300, 1e-6);
}

TEST(ChooseMovingFrame, TakesTheLargestSizeThatMeetsTheBudget) {
  const FrameCostModel model = Measured720p();
  const MovingFrame f = ChooseMovingFrame(model, k720p, 2, 70, {1, 2});
  // Predicted: 20 + s^2 (300 spp + 300) ms: 0.375 at 1 spp 104 ms, 0.25 at
  // 2 spp 76 ms, at 1 spp 57.5 ms.
  EXPECT_EQ(f.scale, 0.25f);
  EXPECT_EQ(f.spp, 1);
  EXPECT_EQ(ChooseMovingFrame(model, k720p, 2, 80, {1, 2}).spp, 2) << "as many samples as fit, up to the scene's";
}

TEST(ChooseMovingFrame, KeepsItsChoiceUntilALargerOneHasRoomToSpare) {
  FrameCostModel model;
  model.Observe({k720p / 16, k720p, 1, 20, 20, 20, 0, 60});  // 60 ms at 0.25: 0.375 would take 20 + 2.25 * 40 = 110
  EXPECT_EQ(ChooseMovingFrame(model, k720p, 1, 100, {0.25f, 1}).scale, 0.25f)
      << "0.375 fits 100 ms, but not within 80% of it";
  EXPECT_EQ(ChooseMovingFrame(model, k720p, 1, 140, {0.25f, 1}).scale, 0.375f);
  EXPECT_EQ(ChooseMovingFrame(model, k720p, 1, 50, {0.25f, 1}).scale, 0.1875f) << "over the budget: down";
}

TEST(ChooseMovingFrame, CountsTheDisplayAtTheRenderedSizeWhereFramesLeaveAtIt) {
  FrameCostModel model;
  model.Observe({k720p / 16, k720p, 1, 10, 10, 40, 0, 60});  // 0.25: 20 ms of render and denoise, 40 of display
  EXPECT_EQ(ChooseMovingFrame(model, k720p, 1, 70, {0.25f, 1}).scale, 0.25f)
      << "upsampled: 0.375 would take 2.25 * 20 + 40 = 85 ms";
  EXPECT_EQ(ChooseMovingFrame(model, k720p, 1, 70, {0.25f, 1}, true).scale, 0.375f)
      << "at its rendered size: 0.25 takes 20 + 40 / 16 = 22.5 ms, 0.375 51 (within 80% of 70), 0.5 90";
}

TEST(ChooseMovingFrame, FallsToTheSmallestSizeWhenNothingFits) {
  const MovingFrame f = ChooseMovingFrame(Measured720p(), k720p, 2, 1, {1, 2});
  EXPECT_EQ(f.scale, kCpuInteractiveScales[std::size(kCpuInteractiveScales) - 1]);
  EXPECT_EQ(f.spp, 1);
}

TEST(ChooseMovingFrame, WaitsForAMeasurement) {
  const MovingFrame f = ChooseMovingFrame(FrameCostModel{}, k720p, 2, 70, {0.5f, 2});
  EXPECT_EQ(f.scale, 0.5f);
  EXPECT_EQ(f.spp, 2);
}

TEST(ChooseStillSpp, StartsAtTheScenesAndRampsWhileTheOverheadDominates) {
  const FrameCostModel model = Measured720p();  // 300 ms a sample, 620 ms of overhead a frame
  EXPECT_EQ(ChooseStillSpp(model, k720p, 2, 0), 2) << "the first still frame shows soon";
  EXPECT_EQ(ChooseStillSpp(model, k720p, 2, 2), 4);
  EXPECT_EQ(ChooseStillSpp(model, k720p, 2, 4), 5) << "620 * 0.7 / 0.3 / 300 = 4.8 samples";
  EXPECT_EQ(ChooseStillSpp(model, k720p, 16, 16), 16) << "never below the scene's";
}

TEST(ChooseStillSpp, StaysAtTheScenesWhereRenderingDominates) {
  FrameCostModel model;
  model.Observe({k720p, k720p, 2, 2000, 10, 5, 10, 2025});
  EXPECT_EQ(ChooseStillSpp(model, k720p, 2, 2), 2);
}

}  // namespace
}  // namespace cinevol
