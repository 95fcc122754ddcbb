// What a CPU frame costs, learnt from the frames so far, and the moving
// frames and still frames chosen from it (FramePipeline on the CPU backend).
//
// A CPU frame's parts scale differently: the render with pixels times
// samples, the denoiser with pixels, the display (and upsampling) with the
// pixels displayed (the viewport, or what rendered where frames leave at
// their rendered size), the refinement with the viewport (still frames
// only), and the rest of the frame interval (waiting for the worker, the
// encoder running beside the next frame on the same cores) with neither. So one measured frame at any size predicts every other size, and a
// view that starts moving after a still period gets the right size from its
// first frame, instead of stepping down one size per few frame times (a
// full-size CPU frame takes seconds).
#pragma once

#include <cstdint>
#include <vector>

namespace cinevol {

// The sizes CPU moving frames may render at, largest first: down to an
// eighth of the viewport's width and height (160x90 for 1280x720).
inline constexpr float kCpuInteractiveScales[] = {1.0f, 0.75f, 0.5f, 0.375f, 0.25f, 0.1875f, 0.125f};
// A larger size is taken only when predicted within this share of the
// budget: every size change restarts the denoiser's history, so the size
// should not flip with each noisy measurement.
inline constexpr double kScaleUpMargin = 0.8;
// Still frames on the CPU take more samples each, so that the denoiser and
// the refinement (paid per frame, at full size) cost at most about this
// share of a frame: 2 spp frames at 720p spent more time denoising and
// refining than rendering. At most kMaxStillSpp: the refinement's error
// estimate needs kMinFramesForError frames (pipeline/refine.h), and 16 of 8
// spp are 128, where a 720p still nears its error target.
inline constexpr double kStillOverheadShare = 0.3;
inline constexpr int kMaxStillSpp = 8;

// One frame's measured parts, in ms; a part not run is 0.
struct FrameCost {
  std::int64_t pixels = 0;            // rendered
  std::int64_t displayed_pixels = 0;  // tone mapped and encoded: the viewport, or `pixels`
  int spp = 1;
  double render_ms = 0, denoise_ms = 0;
  double display_ms = 0;  // upsampling (moving frames) and display
  double refine_ms = 0;   // still frames, at the viewport's size
  double interval_ms = -1;  // from this frame's start to the next one's; < 0: not back to back
};

class FrameCostModel {
 public:
  // A frame's parts; its interval may come later (ObserveInterval), once the
  // next frame starts.
  void Observe(const FrameCost& cost);
  void ObserveInterval(double interval_ms);
  bool known() const { return frames_ > 0; }

  // Predicted interval of a moving frame (no refinement) of `pixels` at
  // `spp`, displayed at `displayed_pixels`.
  double PredictMoving(std::int64_t pixels, int spp, std::int64_t displayed_pixels) const;
  double render_ms_per_sample(std::int64_t pixels) const { return render_ * double(pixels); }
  // What a full-size still frame costs besides its render.
  double StillOverhead(std::int64_t pixels) const;

 private:
  static void Blend(double& average, double sample, bool first);

  int frames_ = 0;
  bool has_overhead_ = false;
  // Running means: ms per rendered pixel and sample, per denoised pixel, per
  // displayed pixel; ms of the refinement at the viewport, and of the rest.
  double render_ = 0, denoise_ = 0, display_ = 0, refine_ = 0, overhead_ = 0;
  FrameCost last_;
};

// What a moving frame renders.
struct MovingFrame {
  float scale = 1;
  int spp = 1;
};

// The largest size (then the most samples, up to `max_spp`) predicted to meet
// `budget_ms`, with hysteresis around `current`: it stays while predicted
// within the budget, and a larger choice is taken only within
// kScaleUpMargin of it. Nothing known yet: `current`. None meets it: the
// smallest size at 1 spp. `at_rendered_size`: frames are displayed at the
// size they render (FrameSettings::frames_at_rendered_size), not the viewport.
MovingFrame ChooseMovingFrame(const FrameCostModel& model, std::int64_t viewport_pixels, int max_spp,
                              double budget_ms, MovingFrame current, bool at_rendered_size = false);

// Samples per pixel for the next still frame at full size: the scene's for
// the first (the still view shows soon), then doubling while the denoiser and
// refinement cost more than kStillOverheadShare of the frame, up to
// kMaxStillSpp (and never below the scene's).
int ChooseStillSpp(const FrameCostModel& model, std::int64_t viewport_pixels, int scene_spp, int previous_spp);

}  // namespace cinevol
