// One level of the refinement's a-trous filter (refine.h, MeanFilterPass) on
// the CPU, as rows that GCC vectorises: a still CPU frame filters both
// halves of the accumulation through three levels of 25 taps, each tap a
// square root, a division and an expf, at full size. The rows and their
// sums are the denoisers' (denoise/cpu_passes.h, CpuAtrousRows); this file
// gives the edge stop.
//
// The maths is the functor's, in the same order, except e^x
// (VectorisableExp, within 2 ulp of expf; denoise/cpu_passes.h). Built for
// AVX2 and the baseline x86-64, picked at run time, with the same results.
#include <cmath>
#include <vector>

#include "core/parallel_for.h"
#include "denoise/cpu_passes.h"
#include "pipeline/refine.h"

namespace cinevol {
namespace {

// fmaxf as C defines it (a NaN loses), as selects, which vectorise.
inline float Fmax(float a, float b) {
  const float larger = a > b ? a : b;  // b where a is NaN
  return b != b ? a : larger;
}

struct MeanPlanes {
  ColourPlanes colour;  // a half's (filtered) mean and its relative variance
  const float* inv_l;   // the centre's 1 / (luminance + dark)
};

// Adds a tap to the row's sums.
__attribute__((target_clones("avx2", "default"))) void AddTap(const MeanPlanes& p, AtrousRowSums s,
                                                             const AtrousRowTap& tap) {
  const ColourPlanes c = p.colour.Offset(tap.row), n = p.colour.Offset(tap.neighbour_row);
  const float* c_inv_l = p.inv_l + tap.row;
  AddAtrousTap(p.colour, s, tap, [=](int x) {
    const float difference =
        Fmax(std::fabs(n.r[x] - c.r[x]), Fmax(std::fabs(n.g[x] - c.g[x]), std::fabs(n.b[x] - c.b[x]))) * c_inv_l[x];
    const float noise = kMeanFilterSigma * std::sqrt(c.v[x] + n.v[x]) + 1e-7f;
    return -difference / noise;
  });
}

constexpr int kPlanes = 5;  // 20 bytes a pixel

}  // namespace

void CpuAtrousLevel(const MeanFilterPass& pass) {
  const int w = pass.width, h = pass.height;
  std::vector<float>* const planes = ThreadPlanes(kPlanes, std::size_t(w) * h);
  ParallelFor(h, [&](std::int64_t y) {
    for (std::size_t i = std::size_t(y) * w, end = i + w; i < end; ++i) {
      const Vec4f c = pass.in[i];
      planes[0][i] = c.x;
      planes[1][i] = c.y;
      planes[2][i] = c.z;
      planes[3][i] = c.w;
      planes[4][i] = 1.0f / (fmaxf(Luminance(Xyz(c)), 0.0f) + pass.dark);
    }
  });
  const MeanPlanes p{{planes[0].data(), planes[1].data(), planes[2].data(), planes[3].data()}, planes[4].data()};
  CpuAtrousRows(w, h, pass.step, pass.out, [&](AtrousRowSums s, const AtrousRowTap& tap) { AddTap(p, s, tap); });
}

}  // namespace cinevol
