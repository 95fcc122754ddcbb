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
  Vec3f box_min;           // world mm: the volume's box
  Vec3f inv_brick_size;    // bricks per mm along each axis

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
      : grid_(&grid), t_min_(t_min), t_max_(t_max) {
    const Vec3f p = (o + d * t_min - grid.box_min) * grid.inv_brick_size;
    const Vec3f dg = d * grid.inv_brick_size;
    for (int a = 0; a < 3; ++a) {
      brick_[a] = MinInt(MaxInt(static_cast<int>(floorf(p[a])), 0), grid.bricks[a] - 1);
      if (dg[a] > 0.0f) {
        delta_t_[a] = 1.0f / dg[a];
        next_t_[a] = t_min + (float(brick_[a] + 1) - p[a]) / dg[a];
        step_[a] = 1;
        limit_[a] = grid.bricks[a];
      } else if (dg[a] < 0.0f) {
        delta_t_[a] = -1.0f / dg[a];
        next_t_[a] = t_min + (float(brick_[a]) - p[a]) / dg[a];
        step_[a] = -1;
        limit_[a] = -1;
      } else {
        delta_t_[a] = kNever;
        next_t_[a] = kNever;
        step_[a] = 0;
        limit_[a] = -2;
      }
    }
  }

  CINEVOL_HD bool Next(MajorantSegment& seg) {
    if (!(t_min_ < t_max_)) return false;
    int axis = next_t_[0] < next_t_[1] ? 0 : 1;
    if (next_t_[2] < next_t_[axis]) axis = 2;
    const float exit = fminf(t_max_, next_t_[axis]);
    seg = {t_min_, exit, grid_->At(brick_)};
    t_min_ = exit;
    brick_[axis] += step_[axis];
    if (brick_[axis] == limit_[axis]) t_min_ = t_max_;
    next_t_[axis] += delta_t_[axis];
    return true;
  }

 private:
  static constexpr float kNever = 3.4e38f;
  const MajorantGridView* grid_;
  float t_min_, t_max_;
  Vec3i brick_;
  float next_t_[3], delta_t_[3];
  int step_[3], limit_[3];
};

// Hard cap on tentative collisions per call: extinction up to 1e6 per mm in a
// brick that is otherwise thin could take millions of null collisions; the
// cap keeps every frame's time bounded (a path that reaches it ends there).
inline constexpr int kMaxTentativeCollisions = 1 << 16;

enum class TrackResult { kLeftRange, kStopped, kBudgetExhausted };

// Draws tentative collisions along o + t d in [t_min, t_max]. For each one
// calls on_collision(t, sigma_maj), which returns false to stop.
template <class OnCollision>
CINEVOL_HD TrackResult SampleMajorant(const MajorantGridView& grid, Vec3f o, Vec3f d, float t_min,
                                      float t_max, Pcg32& rng, OnCollision&& on_collision) {
  MajorantIterator it(grid, o, d, t_min, t_max);
  MajorantSegment seg;
  int budget = kMaxTentativeCollisions;
  while (it.Next(seg)) {
    if (seg.sigma_maj <= 0.0f) continue;  // empty space: skipped
    float t = seg.t_min;
    while (true) {
      t -= logf(1.0f - rng.Uniform()) / seg.sigma_maj;
      if (t >= seg.t_max) break;  // memoryless: restart in the next segment
      if (--budget < 0) return TrackResult::kBudgetExhausted;
      if (!on_collision(t, seg.sigma_maj)) return TrackResult::kStopped;
    }
  }
  return TrackResult::kLeftRange;
}

}  // namespace cinevol
