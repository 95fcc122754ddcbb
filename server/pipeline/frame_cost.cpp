// FrameCostModel: running means of each part's cost per unit it scales with.
#include "pipeline/frame_cost.h"

#include <algorithm>
#include <cmath>
#include <iterator>

namespace cinevol {
namespace {

// Rate of the running means: a change of view or load shows within a few
// frames, one noisy frame (a shared machine) moves them by a third.
constexpr double kRate = 0.35;

}  // namespace

void FrameCostModel::Blend(double& average, double sample, bool first) {
  average = first ? sample : average + kRate * (sample - average);
}

void FrameCostModel::Observe(const FrameCost& c) {
  if (c.pixels <= 0 || c.spp <= 0) return;
  const bool first = frames_ == 0;
  Blend(render_, c.render_ms / (double(c.pixels) * c.spp), first);
  Blend(denoise_, c.denoise_ms / double(c.pixels), first);
  Blend(display_, c.display_ms / double(std::max<std::int64_t>(c.displayed_pixels, 1)), first);
  if (c.refine_ms > 0 || first) Blend(refine_, c.refine_ms, first || refine_ == 0);
  last_ = c;
  ++frames_;
  if (c.interval_ms >= 0) ObserveInterval(c.interval_ms);
}

void FrameCostModel::ObserveInterval(double interval_ms) {
  if (frames_ == 0) return;
  const FrameCost& c = last_;
  const double parts = c.render_ms + c.denoise_ms + c.display_ms + c.refine_ms;
  Blend(overhead_, std::max(interval_ms - parts, 0.0), !has_overhead_);
  has_overhead_ = true;
}

double FrameCostModel::PredictMoving(std::int64_t pixels, int spp, std::int64_t displayed_pixels) const {
  return double(pixels) * (render_ * spp + denoise_) + double(displayed_pixels) * display_ + overhead_;
}

double FrameCostModel::StillOverhead(std::int64_t pixels) const {
  return double(pixels) * (denoise_ + display_) + refine_;
}

MovingFrame ChooseMovingFrame(const FrameCostModel& model, std::int64_t viewport_pixels, int max_spp,
                              double budget_ms, MovingFrame current, bool at_rendered_size) {
  if (!model.known()) return current;
  max_spp = std::max(max_spp, 1);
  auto predict = [&](const MovingFrame& f) {
    const double side = f.scale;
    const std::int64_t pixels = std::max<std::int64_t>(1, std::llround(double(viewport_pixels) * side * side));
    return model.PredictMoving(pixels, f.spp, at_rendered_size ? pixels : viewport_pixels);
  };
  // Candidates in order of preference: the larger size first, then more samples.
  std::vector<MovingFrame> candidates;
  for (const float scale : kCpuInteractiveScales) {
    for (int spp = max_spp; spp >= 1; --spp) candidates.push_back({scale, spp});
  }
  auto first_within = [&](double limit) {
    for (std::size_t i = 0; i < candidates.size(); ++i) {
      if (predict(candidates[i]) <= limit) return i;
    }
    return candidates.size();
  };
  std::size_t now = candidates.size();
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    if (candidates[i].scale == current.scale && candidates[i].spp == std::min(current.spp, max_spp)) now = i;
  }
  const std::size_t fits = first_within(budget_ms);
  if (now == candidates.size() || predict(candidates[now]) > budget_ms) {
    return fits < candidates.size() ? candidates[fits] : candidates.back();
  }
  const std::size_t roomy = first_within(kScaleUpMargin * budget_ms);
  return roomy < now ? candidates[roomy] : candidates[now];
}

int ChooseStillSpp(const FrameCostModel& model, std::int64_t viewport_pixels, int scene_spp, int previous_spp) {
  scene_spp = std::max(scene_spp, 1);
  if (previous_spp <= 0 || !model.known()) return scene_spp;
  const int cap = std::max(kMaxStillSpp, scene_spp);
  const double per_sample = model.render_ms_per_sample(viewport_pixels);
  const double overhead = model.StillOverhead(viewport_pixels);
  // The render that keeps the rest within kStillOverheadShare of the frame.
  const double wanted = per_sample > 0 ? overhead * (1 - kStillOverheadShare) / kStillOverheadShare / per_sample : cap;
  const int spp = std::clamp(int(std::ceil(wanted)), scene_spp, cap);
  return std::min(spp, std::max(2 * previous_spp, scene_spp));  // ramps up: each frame at most twice the last
}

}  // namespace cinevol
