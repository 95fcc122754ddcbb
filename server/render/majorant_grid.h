// Free-path sampling against a transfer-function-aware majorant grid, shaped
// like pbrt-v4's SampleT_maj: a DDA walks the bricks a ray crosses, yielding
// segments of constant majorant; exponential steps are drawn inside each and
// a callback classifies every tentative collision. Empty bricks (majorant 0)
// cost one DDA step and no volume fetch.
#pragma once

#include <cstdint>

#include "core/hd.h"
#include "core/rng.h"
#include "core/vec.h"

namespace cinevol {

// The brick grid as kernels see it: one majorant (per mm) per brick.
struct MajorantGridView {
  const float* majorant = nullptr;  // bricks.x * bricks.y * bricks.z, x fastest
  Vec3i bricks;
  Vec3f box_min;         // world mm: the volume's box
  Vec3f inv_brick_size;  // bricks per mm along each axis

  CINEVOL_HD float At(Vec3i b) const {
    return LoadReadOnly(majorant + (std::int64_t(b.z) * bricks.y + b.y) * bricks.x + b.x);
  }
};

struct MajorantSegment {
  float t_min, t_max;
  float sigma_maj;
};

// Visits the bricks along o + t d for t in [t_min, t_max], in order. The ray
// must lie inside the volume's box over that range (clip it first).
class MajorantIterator {
 public:
  CINEVOL_HD MajorantIterator(const MajorantGridView& grid, Vec3f o, Vec3f d, float t_min, float t_max)
      : majorant_(grid.majorant), t_min_(t_min), t_max_(t_max) {
    const Vec3f p = (o + d * t_min - grid.box_min) * grid.inv_brick_size;
    const Vec3f dg = d * grid.inv_brick_size;
    int bx, by, bz;
    x_ = Axis(p.x, dg.x, t_min, grid.bricks.x, 1, bx);
    y_ = Axis(p.y, dg.y, t_min, grid.bricks.y, grid.bricks.x, by);
    z_ = Axis(p.z, dg.z, t_min, grid.bricks.z, grid.bricks.x * grid.bricks.y, bz);
    // At most kMaxVoxels bricks (core/volume.h): an int holds the index.
    index_ = (bz * grid.bricks.y + by) * grid.bricks.x + bx;
  }

  CINEVOL_HD bool Next(MajorantSegment& seg) {
    if (!(t_min_ < t_max_)) return false;
    seg.t_min = t_min_;
    seg.sigma_maj = LoadReadOnly(majorant_ + index_);
    // Step along the axis whose brick boundary comes first. One call per
    // axis, not a reference or an index chosen at run time: that keeps every
    // field in registers on a GPU.
    if (x_.next_t < y_.next_t && x_.next_t < z_.next_t) {
      Step(x_);
    } else if (y_.next_t < z_.next_t) {
      Step(y_);
    } else {
      Step(z_);
    }
    seg.t_max = t_min_;
    return true;
  }

 private:
  static constexpr float kNever = 3.4e38f;

  // One axis of the walk: the bricks left before the ray leaves the grid
  // along it, the step of the brick index, and where and how often the next
  // boundary comes. The index moves by the stride, not recomputed from three
  // brick coordinates a step.
  struct AxisState {
    int left, stride;
    float next_t, delta_t;
  };

  CINEVOL_HD void Step(AxisState& a) {
    t_min_ = fminf(t_max_, a.next_t);
    index_ += a.stride;
    if (--a.left == 0) t_min_ = t_max_;
    a.next_t += a.delta_t;
  }

  // p: entry position in bricks; d: direction in bricks per unit t; stride:
  // the index's step per brick along the axis. `brick` takes the entry brick.
  CINEVOL_HD static AxisState Axis(float p, float d, float t_min, int bricks, int stride, int& brick) {
    brick = MinInt(MaxInt(static_cast<int>(floorf(p)), 0), bricks - 1);
    if (d > 0.0f) return {bricks - brick, stride, t_min + (float(brick + 1) - p) / d, 1.0f / d};
    if (d < 0.0f) return {brick + 1, -stride, t_min + (float(brick) - p) / d, -1.0f / d};
    return {-1, 0, kNever, kNever};  // never stepped along
  }

  const float* majorant_;
  int index_;
  float t_min_, t_max_;
  AxisState x_, y_, z_;
};

// Hard cap on the tentative collisions of one path, over all its tracking
// calls (free flights and shadow rays together): with it, a path's cost is
// bounded whatever the transfer function. A path that reaches it ends there,
// as if absorbed. Extinction is clamped per voxel (kMaxOpticalDepthPerVoxel,
// render/scene_data.h), so that takes about 2000 voxels of majorant at the
// clamp without a real collision: no ordinary path comes near it.
inline constexpr int kMaxPathCollisions = 1 << 16;

enum class TrackResult { kLeftRange, kStopped, kBudgetExhausted };

// Draws tentative collisions along o + t d in [t_min, t_max]. For each one
// calls on_collision(t, inv_majorant), with 1 / the majorant there (a
// multiplication then compares or weighs the extinction, not a division a
// collision), which returns false to stop. Each collision takes one from
// `budget`; none left: kBudgetExhausted.
template <class OnCollision>
CINEVOL_HD TrackResult SampleMajorant(const MajorantGridView& grid, Vec3f o, Vec3f d, float t_min, float t_max,
                                      Pcg32& rng, int& budget, OnCollision&& on_collision) {
  MajorantIterator it(grid, o, d, t_min, t_max);
  MajorantSegment seg;
  while (it.Next(seg)) {
    if (seg.sigma_maj <= 0.0f) continue;  // empty space: skipped
    // Steps add up from the segment's start, not onto t: far from the ray's
    // origin a step smaller than t's precision would leave t where it was.
    const float length = seg.t_max - seg.t_min;
    // An exponential step is -ln(1 - u) / sigma = log2(1 - u) * (-ln 2 / sigma):
    // one division a segment, not one a step.
    const float inv_majorant = 1.0f / seg.sigma_maj;
    const float step_scale = -0.69314718f * inv_majorant;
    float dt = 0.0f;
    while (true) {
      dt += FastLog2(1.0f - rng.Uniform()) * step_scale;
      if (dt >= length) break;  // memoryless: restart in the next segment
      if (--budget < 0) return TrackResult::kBudgetExhausted;
      if (!on_collision(fminf(seg.t_min + dt, seg.t_max), inv_majorant)) return TrackResult::kStopped;
    }
  }
  return TrackResult::kLeftRange;
}

}  // namespace cinevol
