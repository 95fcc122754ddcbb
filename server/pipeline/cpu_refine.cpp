// One level of the refinement's a-trous filter (refine.h, MeanFilterPass) on
// the CPU, as rows that GCC vectorises: a still CPU frame filters both
// halves of the accumulation through three levels of 25 taps, each tap a
// square root, a division and an expf, at full size.
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
  const float *r, *g, *b, *v;
  const float* inv_l;  // the centre's 1 / (luminance + dark)
};

struct RowSums {
  float *r, *g, *b, *v, *w;
};

__attribute__((target_clones("avx2", "default"))) void AddTap(const MeanPlanes& p, RowSums s, int width, int y,
                                                             int ny, int shift, int x0, int x1, float kernel_weight) {
  const std::size_t row = std::size_t(y) * width, neighbour_row = std::size_t(ny) * width + shift;
  const float *__restrict c_r = p.r + row, *__restrict c_g = p.g + row, *__restrict c_b = p.b + row;
  const float *__restrict c_v = p.v + row, *__restrict c_inv_l = p.inv_l + row;
  const float *__restrict n_r = p.r + neighbour_row, *__restrict n_g = p.g + neighbour_row;
  const float *__restrict n_b = p.b + neighbour_row, *__restrict n_v = p.v + neighbour_row;
  float *__restrict s_r = s.r, *__restrict s_g = s.g, *__restrict s_b = s.b, *__restrict s_v = s.v;
  float* __restrict s_w = s.w;
  // The planes and sums never overlap; GCC does not take __restrict on
  // locals, and 10 run-time alias checks are its limit.
#pragma GCC ivdep
  for (int x = x0; x < x1; ++x) {
    const float difference =
        Fmax(std::fabs(n_r[x] - c_r[x]), Fmax(std::fabs(n_g[x] - c_g[x]), std::fabs(n_b[x] - c_b[x]))) * c_inv_l[x];
    const float noise = kMeanFilterSigma * std::sqrt(c_v[x] + n_v[x]) + 1e-7f;
    const float w = kernel_weight * VectorisableExp(-difference / noise);
    s_r[x] += n_r[x] * w;
    s_g[x] += n_g[x] * w;
    s_b[x] += n_b[x] * w;
    s_v[x] += n_v[x] * w * w;
    s_w[x] += w;
  }
}

constexpr int kPlanes = 5;

}  // namespace

void CpuMeanFilterLevel(const MeanFilterPass& pass) {
  const int w = pass.width, h = pass.height;
  const std::size_t n = std::size_t(w) * h;
  thread_local std::vector<float> own_planes[kPlanes];  // 20 bytes a pixel, kept between calls
  std::vector<float>* const planes = own_planes;  // the helpers' own thread_local would be another
  for (int k = 0; k < kPlanes; ++k) planes[k].resize(n);
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
  const MeanPlanes p{planes[0].data(), planes[1].data(), planes[2].data(), planes[3].data(), planes[4].data()};
  ParallelFor(h, [&](std::int64_t yy) {
    const int y = int(yy);
    thread_local std::vector<float> sums;
    sums.assign(std::size_t(5) * w, 0.0f);
    const RowSums s{sums.data(), sums.data() + w, sums.data() + 2 * w, sums.data() + 3 * w, sums.data() + 4 * w};
    const float kernel[3] = {3.0f / 8.0f, 1.0f / 4.0f, 1.0f / 16.0f};
    for (int dy = -2; dy <= 2; ++dy) {
      const int ny = y + dy * pass.step;
      if (ny < 0 || ny >= h) continue;
      for (int dx = -2; dx <= 2; ++dx) {
        const int shift = dx * pass.step;
        const int x0 = MaxInt(0, -shift), x1 = MinInt(w, w - shift);
        if (x0 >= x1) continue;
        AddTap(p, s, w, y, ny, shift, x0, x1, kernel[dx < 0 ? -dx : dx] * kernel[dy < 0 ? -dy : dy]);
      }
    }
    for (int x = 0; x < w; ++x) {
      const Vec3f sum{s.r[x], s.g[x], s.b[x]};
      const float weight = s.w[x];
      pass.out[y * w + x] = ToVec4(sum / weight, s.v[x] / (weight * weight));
    }
  });
}

}  // namespace cinevol
