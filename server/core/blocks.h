// Per-block summaries of a voxel grid: every summary the server keeps per
// block (a volume's value ranges for framing, the renderer's brick ranges
// and brick labels for empty-space skipping, the blocks holding a shown
// label) walks the grid here, so the blocks' layout (x fastest, partial
// blocks at the high edges) and the split over threads are written once.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "core/parallel_for.h"
#include "core/vec.h"

namespace cinevol {

// Blocks of `block_size` voxels along each axis over a grid of `dims` voxels.
CINEVOL_HD Vec3i BlockCounts(Vec3i dims, Vec3i block_size) {
  return {(dims.x + block_size.x - 1) / block_size.x, (dims.y + block_size.y - 1) / block_size.y,
          (dims.z + block_size.z - 1) / block_size.z};
}

inline std::size_t BlockTotal(Vec3i blocks) { return std::size_t(blocks.x) * blocks.y * blocks.z; }

// Calls f(block index, lo, hi) for every block, with the voxels [lo, hi] it
// covers plus `margin` beyond (what lookups inside it read), one slab of
// blocks (fixed z) per task: each block is visited by one thread, once.
template <class F>
void ForEachBlock(Vec3i dims, Vec3i block_size, int margin, F&& f) {
  const Vec3i blocks = BlockCounts(dims, block_size);
  ParallelFor(blocks.z, [&](std::int64_t bz) {
    for (int by = 0; by < blocks.y; ++by) {
      for (int bx = 0; bx < blocks.x; ++bx) {
        const Vec3i b{bx, by, int(bz)};
        Vec3i lo, hi;
        for (int a = 0; a < 3; ++a) {
          lo[a] = std::max(0, b[a] * block_size[a] - margin);
          hi[a] = std::min(dims[a] - 1, (b[a] + 1) * block_size[a] + margin - 1);
        }
        f((std::size_t(bz) * blocks.y + by) * blocks.x + bx, lo, hi);
      }
    }
  });
}

// Calls f(value) for every voxel of [lo, hi] of a grid `dims` wide, row by row.
template <class T, class F>
void ForEachVoxel(const T* voxels, Vec3i dims, Vec3i lo, Vec3i hi, F&& f) {
  for (int z = lo.z; z <= hi.z; ++z) {
    for (int y = lo.y; y <= hi.y; ++y) {
      const T* row = voxels + (std::size_t(z) * dims.y + y) * dims.x;
      for (int x = lo.x; x <= hi.x; ++x) f(row[x]);
    }
  }
}

}  // namespace cinevol
