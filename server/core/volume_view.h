// The volume as kernels see it: 16-bit voxels, trilinear or tricubic
// (B-spline) sampling with clamp-to-edge, and central-difference gradients. Positions are world mm;
// the box [0, dims*spacing] is centred at the origin, voxel i's centre sits at
// (i + 0.5) * spacing from the box's corner (docs/architecture.md).
#pragma once

#include <cstdint>

#include "core/hd.h"
#include "core/vec.h"

namespace cinevol {

// How values are reconstructed between voxel centres (Scene render.reconstruction).
enum class Reconstruction { kTrilinear, kTricubic };

// Voxels a lookup reads beyond the cell it falls in, on each side: what the
// majorant grid's brick ranges must include.
inline int LookupMargin(Reconstruction r) { return r == Reconstruction::kTricubic ? 2 : 1; }

struct VolumeView {
  const std::uint16_t* voxels = nullptr;  // x fastest; in the backend's memory
  // CUDA only, where set: the same voxels as a 3D texture (cudaTextureObject_t,
  // device/volume_texture.h) that Sample reads instead of `voxels`.
  unsigned long long texture = 0;
  Vec3i dims;
  Vec3f spacing;      // mm
  Vec3f inv_spacing;  // 1 / spacing
  Vec3f box_min, box_max;  // world mm
  bool tricubic = false;   // cubic B-spline reconstruction instead of trilinear

  // Voxel (x, y, z) clamped to the grid.
  CINEVOL_HD float Fetch(int x, int y, int z) const {
    x = x < 0 ? 0 : (x >= dims.x ? dims.x - 1 : x);
    y = y < 0 ? 0 : (y >= dims.y ? dims.y - 1 : y);
    z = z < 0 ? 0 : (z >= dims.z ? dims.z - 1 : z);
    const std::int64_t i = (std::int64_t(z) * dims.y + y) * dims.x + x;
    return static_cast<float>(LoadReadOnly(voxels + i));
  }

  // Continuous voxel coordinates: voxel centres at integers.
  CINEVOL_HD Vec3f ToVoxel(Vec3f p) const { return (p - box_min) * inv_spacing - Vec3f{0.5f, 0.5f, 0.5f}; }

  // The reconstructed stored value at world position p, as `tricubic` says.
  CINEVOL_HD float Sample(Vec3f p) const { return tricubic ? SampleAs<true>(p) : SampleAs<false>(p); }
  CINEVOL_HD float SampleTrilinear(Vec3f p) const { return SampleAs<false>(p); }

  // The same with the reconstruction fixed at compile time (the integrator's
  // specialisations): no branch, and no registers for the other one. On a
  // GPU the texture where there is one, else the voxels one by one;
  // kTextureOnly: the texture, which the caller knows is there, and no code
  // for the voxels (the specialised render kernels', render/render_scene.h,
  // ReadsTexturesOnly). The CPU reads its voxels either way.
  template <bool kTricubic, bool kTextureOnly = false>
  CINEVOL_HD float SampleAs(Vec3f p) const {
#if CINEVOL_DEVICE_PASS
    if (kTextureOnly || texture) return kTricubic ? TricubicFromTexture(p) : TrilinearFromTexture(p);
#endif
    return kTricubic ? TricubicFromVoxels(p) : TrilinearFromVoxels(p);
  }

#if CINEVOL_DEVICE_PASS
  // Texel centres at i + 0.5, as ToVoxel's +0.5 gives them.
  __device__ float TrilinearFromTexture(Vec3f p) const {
    const Vec3f t = (p - box_min) * inv_spacing;
    return 65535.0f * tex3D<float>(texture, t.x, t.y, t.z);
  }

  // GPU Gems 2, ch. 20: each axis's four B-spline weights as two linear
  // fetches placed between voxel pairs, so 8 hardware trilinear fetches do it.
  __device__ float TricubicFromTexture(Vec3f p) const {
    const Vec3f q = ToVoxel(p);
    const Vec3f f{floorf(q.x), floorf(q.y), floorf(q.z)};
    Vec3f w[4];
    BSplineWeights(q - f, w);
    const Vec3f g0 = w[0] + w[1], g1 = w[2] + w[3];
    const Vec3f h0 = f + w[1] / g0 - Vec3f{0.5f, 0.5f, 0.5f}, h1 = f + w[3] / g1 + Vec3f{1.5f, 1.5f, 1.5f};
    auto at = [&](float x, float y, float z) { return tex3D<float>(texture, x, y, z); };
    const float a = g0.z * (g0.y * (g0.x * at(h0.x, h0.y, h0.z) + g1.x * at(h1.x, h0.y, h0.z)) +
                            g1.y * (g0.x * at(h0.x, h1.y, h0.z) + g1.x * at(h1.x, h1.y, h0.z)));
    const float b = g1.z * (g0.y * (g0.x * at(h0.x, h0.y, h1.z) + g1.x * at(h1.x, h0.y, h1.z)) +
                            g1.y * (g0.x * at(h0.x, h1.y, h1.z) + g1.x * at(h1.x, h1.y, h1.z)));
    return 65535.0f * (a + b);
  }
#endif

  // The voxels read one by one: the CPU's path, and a GPU's where the volume
  // exceeds its texture size (out of line there, so the kernels carry its
  // code once, not at every lookup).
  CINEVOL_HD_COLD float TrilinearFromVoxels(Vec3f p) const {
    const Vec3f q = ToVoxel(p);
    const float fx = floorf(q.x), fy = floorf(q.y), fz = floorf(q.z);
    const int x = static_cast<int>(fx), y = static_cast<int>(fy), z = static_cast<int>(fz);
    const float tx = q.x - fx, ty = q.y - fy, tz = q.z - fz;
    const float c00 = Fetch(x, y, z) + tx * (Fetch(x + 1, y, z) - Fetch(x, y, z));
    const float c10 = Fetch(x, y + 1, z) + tx * (Fetch(x + 1, y + 1, z) - Fetch(x, y + 1, z));
    const float c01 = Fetch(x, y, z + 1) + tx * (Fetch(x + 1, y, z + 1) - Fetch(x, y, z + 1));
    const float c11 = Fetch(x, y + 1, z + 1) + tx * (Fetch(x + 1, y + 1, z + 1) - Fetch(x, y + 1, z + 1));
    const float c0 = c00 + ty * (c10 - c00);
    const float c1 = c01 + ty * (c11 - c01);
    return c0 + tz * (c1 - c0);
  }

  // Uniform cubic B-spline over the 4^3 voxels around p, as
  // TrilinearFromVoxels for the tricubic reconstruction. Its weights are
  // non-negative and sum to 1, so the value stays within those voxels'
  // range: the majorant grid bounds it with a two-voxel brick margin.
  CINEVOL_HD_COLD float TricubicFromVoxels(Vec3f p) const {
    const Vec3f q = ToVoxel(p);
    const Vec3f f{floorf(q.x), floorf(q.y), floorf(q.z)};
    Vec3f w[4];
    BSplineWeights(q - f, w);
    const int x = static_cast<int>(f.x) - 1, y = static_cast<int>(f.y) - 1, z = static_cast<int>(f.z) - 1;
    float sum = 0.0f;
    for (int k = 0; k < 4; ++k) {
      float plane = 0.0f;
      for (int j = 0; j < 4; ++j) {
        float row = 0.0f;
        for (int i = 0; i < 4; ++i) row += w[i].x * Fetch(x + i, y + j, z + k);
        plane += w[j].y * row;
      }
      sum += w[k].z * plane;
    }
    return sum;
  }

  // Cubic B-spline weights of the voxels at offsets -1, 0, 1, 2 from the
  // cell's corner, for fractional position t along each axis.
  CINEVOL_HD static void BSplineWeights(Vec3f t, Vec3f w[4]) {
    const Vec3f one{1, 1, 1};
    const Vec3f t2 = t * t, t3 = t2 * t, s = one - t;
    w[0] = s * s * s * (1.0f / 6.0f);
    w[1] = (t3 * 3.0f - t2 * 6.0f + one * 4.0f) * (1.0f / 6.0f);
    w[3] = t3 * (1.0f / 6.0f);
    w[2] = one - w[0] - w[1] - w[3];
  }

  // Gradient of the stored value per mm, by central differences one voxel apart.
  template <bool kTricubic, bool kTextureOnly = false>
  CINEVOL_HD Vec3f Gradient(Vec3f p) const {
    const Vec3f dx{spacing.x, 0, 0}, dy{0, spacing.y, 0}, dz{0, 0, spacing.z};
    auto at = [&](Vec3f q) { return SampleAs<kTricubic, kTextureOnly>(q); };
    return Vec3f{at(p + dx) - at(p - dx), at(p + dy) - at(p - dy), at(p + dz) - at(p - dz)} * (0.5f * inv_spacing);
  }
};

// Ray-box slab test; returns false when the ray misses [lo, hi].
CINEVOL_HD bool IntersectBox(Vec3f origin, Vec3f inv_dir, Vec3f lo, Vec3f hi, float& t0, float& t1) {
  float tmin = 0.0f, tmax = 3.4e38f;
  for (int a = 0; a < 3; ++a) {
    float ta = (lo[a] - origin[a]) * inv_dir[a];
    float tb = (hi[a] - origin[a]) * inv_dir[a];
    if (ta > tb) {
      const float t = ta;
      ta = tb;
      tb = t;
    }
    // NaN (0 * inf on a slab face) compares false and leaves the bounds alone.
    tmin = ta > tmin ? ta : tmin;
    tmax = tb < tmax ? tb : tmax;
  }
  t0 = tmin;
  t1 = tmax;
  return tmin <= tmax;
}

}  // namespace cinevol
