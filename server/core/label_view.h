// A segmentation as kernels see it: the label of the voxel nearest a point,
// and what that label does to the image's classification. Nearest lookup
// keeps label boundaries sharp: no blend of two labels' styles.
#pragma once

#include <cstdint>

#include "core/hd.h"
#include "core/vec.h"
#include "core/volume_view.h"

namespace cinevol {

// One label's effect; the default changes nothing (no segmentation).
struct LabelMaterial {
  Vec3f color;                 // diffuse colour, where has_color
  float opacity_scale = 1.0f;  // 0: hidden
  int has_color = 0;
  int table = 0;               // transfer table: 0 the image's, k the label's own (k - 1)
};

struct LabelView {
  const std::uint16_t* voxels = nullptr;     // on the image's grid; nullptr: no segmentation
  const LabelMaterial* materials = nullptr;  // by label value, for every value up to the largest present

  CINEVOL_HD LabelMaterial At(const VolumeView& grid, Vec3f p) const {
    return materials[LoadReadOnly(voxels + NearestVoxel(grid, p))];
  }

  // The index of the voxel nearest p (clamped to the grid): where the label of p is stored.
  CINEVOL_HD static std::int64_t NearestVoxel(const VolumeView& grid, Vec3f p) {
    const Vec3f q = grid.ToVoxel(p);
    const int x = ClampInt(static_cast<int>(floorf(q.x + 0.5f)), 0, grid.dims.x - 1);
    const int y = ClampInt(static_cast<int>(floorf(q.y + 0.5f)), 0, grid.dims.y - 1);
    const int z = ClampInt(static_cast<int>(floorf(q.z + 0.5f)), 0, grid.dims.z - 1);
    return (std::int64_t(z) * grid.dims.y + y) * grid.dims.x + x;
  }

 private:
  CINEVOL_HD static int ClampInt(int v, int lo, int hi) { return v < lo ? lo : (v > hi ? hi : v); }
};

}  // namespace cinevol
