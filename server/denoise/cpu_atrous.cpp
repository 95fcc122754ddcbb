// One a-trous level (baselines.h, AtrousPass) on the CPU, as rows that GCC
// vectorises: the per-tap weights of the functor, computed for a whole row
// at a time from planes (luminance, escaped, the level's colour and variance)
// instead of pixel by pixel from the frame's structures. The a-trous levels
// were most of a CPU frame's denoising (five levels of 25 taps, each tap an
// expf and a square root: 48% of a 720p CPU server's profile). The rows and
// their sums are cpu_passes.h's (CpuAtrousRows, AddAtrousTap), shared with
// the refinement's filter; this file gives the edge stops.
//
// The maths is the functor's, operation for operation and in the same order
// (taps in the same order, the same sums), except e^x: glibc's expf does not
// vectorise, so VectorisableExp (cpu_passes.h) stands in for it, where the
// functor takes 2 to the power of the exponent times log2(e) (FastExp2, the
// GPU's own instruction).
// The row kernel is built for AVX2 and for the baseline x86-64 (SSE2), picked
// at run time; both give the same results (no FMA contraction: ISO C++ mode).
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/parallel_for.h"
#include "denoise/baselines.h"
#include "denoise/cpu_passes.h"
#include "denoise/reprojection.h"

namespace cinevol {
namespace {

// What the taps read, one plane per quantity, for contiguous loads (the
// edge guides too, which the GPU reads packed).
struct AtrousPlanes {
  ColourPlanes colour;         // the level's colour and variance
  const float* l;              // luminance of the colour
  const float* depth;          // EdgeGuidesPass
  const float* escaped;        // 1 where the ray escaped
  const float* coverage;
  const float* l_scale;        // the centre's luminance stop: 1 / (sigma sqrt(blurred variance))
  const float* z_scale;        // the centre's depth stop
  // AtrousPass::normals, where set: the surface normal's components and
  // length, and the stop's scale
  const float *nx = nullptr, *ny = nullptr, *nz = nullptr, *n_length = nullptr;
  float normal_stop = 0.0f;
};

// Adds a tap to the row's sums: the luminance stop SVGF's (|dl| / (sigma
// dev)) or squared (AtrousPass::squared_luminance). Inlined into the two
// row kernels below, each built for AVX2 and the baseline x86-64.
template <bool kSquared, bool kNormals>
inline __attribute__((always_inline)) void AddEdgeStoppedTap(const AtrousPlanes& p, AtrousRowSums s,
                                                             const AtrousRowTap& tap) {
  const std::ptrdiff_t row = tap.row, neighbour_row = tap.neighbour_row;
  const float *c_l = p.l + row, *c_depth = p.depth + row, *c_escaped = p.escaped + row;
  const float *c_coverage = p.coverage + row, *c_l_scale = p.l_scale + row, *c_z_scale = p.z_scale + row;
  const float *n_l = p.l + neighbour_row, *n_depth = p.depth + neighbour_row;
  const float *n_escaped = p.escaped + neighbour_row, *n_coverage = p.coverage + neighbour_row;
  AddAtrousTap(p.colour, s, tap, [=](int x) {
    // 0 where either ray escaped, as two selects (an || is a branch GCC
    // does not vectorise).
    const float depth_step = std::fabs(n_depth[x] - c_depth[x]);
    const float centre_hit = c_escaped[x] != 0.0f ? 0.0f : depth_step;
    const float dz = n_escaped[x] != 0.0f ? 0.0f : centre_hit;
    const float dc = std::fabs(n_coverage[x] - c_coverage[x]);
    const float dl = std::fabs(n_l[x] - c_l[x]) * c_l_scale[x];
    const float e = -(kSquared ? dl * dl : dl) - dz * c_z_scale[x] - dc * AtrousPass::kCoverageStop;
    if constexpr (!kNormals) {
      return e;
    } else {
      const float dot = p.nx[row + x] * p.nx[neighbour_row + x] + p.ny[row + x] * p.ny[neighbour_row + x] +
                        p.nz[row + x] * p.nz[neighbour_row + x];
      return e - p.normal_stop * std::fmax(p.n_length[row + x] * p.n_length[neighbour_row + x] - dot, 0.0f);
    }
  });
}

__attribute__((target_clones("avx2", "default"))) void AddTap(const AtrousPlanes& p, AtrousRowSums s,
                                                             const AtrousRowTap& tap) {
  AddEdgeStoppedTap<false, false>(p, s, tap);
}

__attribute__((target_clones("avx2", "default"))) void AddTapSquared(const AtrousPlanes& p, AtrousRowSums s,
                                                                    const AtrousRowTap& tap) {
  AddEdgeStoppedTap<true, false>(p, s, tap);
}

__attribute__((target_clones("avx2", "default"))) void AddTapNormals(const AtrousPlanes& p, AtrousRowSums s,
                                                                     const AtrousRowTap& tap) {
  AddEdgeStoppedTap<false, true>(p, s, tap);
}

__attribute__((target_clones("avx2", "default"))) void AddTapSquaredNormals(const AtrousPlanes& p, AtrousRowSums s,
                                                                            const AtrousRowTap& tap) {
  AddEdgeStoppedTap<true, true>(p, s, tap);
}

constexpr int kPlanes = 10;       // 40 bytes a pixel
constexpr int kNormalPlanes = 4;  // and 16 more with AtrousPass::normals

// The planes of one level, per pixel, as the functor computes them.
void FillPlanes(const AtrousPass& pass, std::vector<float>* planes, int y) {
  const int w = pass.width, h = pass.height;
  for (int x = 0; x < w; ++x) {
    const int i = y * w + x;
    const Vec4f c = pass.in[i];
    float variance = 0.0f, vw = 0.0f;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = MinInt(MaxInt(x + dx, 0), w - 1), ny = MinInt(MaxInt(y + dy, 0), h - 1);
        const float kw = (dx == 0 ? 0.5f : 0.25f) * (dy == 0 ? 0.5f : 0.25f);
        variance += pass.in[ny * w + nx].w * kw;
        vw += kw;
      }
    }
    const float z = pass.guides[i].depth;
    planes[0][i] = c.x;
    planes[1][i] = c.y;
    planes[2][i] = c.z;
    planes[3][i] = c.w;
    planes[4][i] = Luminance(Xyz(c));
    planes[5][i] = AtrousPass::Hit(z) ? 0.0f : 1.0f;
    planes[6][i] = 1.0f / (pass.sigma_luminance * sqrtf(pass.StopVariance(variance / vw)) + 1e-10f);
    planes[7][i] = 1.0f / (pass.sigma_depth * 0.01f * fmaxf(z, 1e-3f) * float(pass.step) + 1e-6f);
    planes[8][i] = z;
    planes[9][i] = pass.guides[i].coverage;
    if (pass.normals) {
      const Vec3f n = pass.normals[i];
      planes[kPlanes][i] = n.x;
      planes[kPlanes + 1][i] = n.y;
      planes[kPlanes + 2][i] = n.z;
      planes[kPlanes + 3][i] = Length(n);
    }
  }
}

}  // namespace

void CpuAtrousLevel(const AtrousPass& pass) {
  const int w = pass.width, h = pass.height;
  std::vector<float>* const planes = ThreadPlanes(kPlanes + (pass.normals ? kNormalPlanes : 0), std::size_t(w) * h);
  ParallelFor(h, [&](std::int64_t y) { FillPlanes(pass, planes, int(y)); });
  const bool normals = pass.normals != nullptr;
  const auto normal_plane = [&](int k) { return normals ? planes[kPlanes + k].data() : nullptr; };
  const AtrousPlanes p{{planes[0].data(), planes[1].data(), planes[2].data(), planes[3].data()},
                       planes[4].data(),
                       planes[8].data(),
                       planes[5].data(),
                       planes[9].data(),
                       planes[6].data(),
                       planes[7].data(),
                       normal_plane(0),
                       normal_plane(1),
                       normal_plane(2),
                       normal_plane(3),
                       pass.normal_stop};
  const auto add_tap = normals ? (pass.squared_luminance ? AddTapSquaredNormals : AddTapNormals)
                               : (pass.squared_luminance ? AddTapSquared : AddTap);
  CpuAtrousRows(w, h, pass.step, pass.out, [&](AtrousRowSums s, const AtrousRowTap& tap) { add_tap(p, s, tap); });
}

}  // namespace cinevol
