// One a-trous level (baselines.h, AtrousPass) on the CPU, as rows that GCC
// vectorises: the per-tap weights of the functor, computed for a whole row
// at a time from planes (luminance, depth, the level's colour and variance)
// instead of pixel by pixel from the frame's structures. The a-trous levels
// were most of a CPU frame's denoising (five levels of 25 taps, each tap an
// expf and a square root: 48% of a 720p CPU server's profile).
//
// The maths is the functor's, operation for operation and in the same order
// (taps in the same order, the same sums), except e^x: glibc's expf does not
// vectorise, so VectorisableExp (cpu_passes.h) stands in for it.
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

// What the taps read, one plane per quantity, for contiguous loads.
struct AtrousPlanes {
  const float *r, *g, *b, *v;  // the level's colour and variance
  const float* l;              // luminance of the colour
  const float* depth;          // AtrousPass::Depth
  const float* escaped;        // 1 where the ray escaped
  const float* coverage;
  const float* l_scale;        // the centre's luminance stop: 1 / (sigma sqrt(blurred variance))
  const float* z_scale;        // the centre's depth stop
};

struct RowSums {
  float *r, *g, *b, *v, *w;
};

// Adds the taps at (dx, dy) * step for pixels [x0, x1) of row y (whose
// neighbours all lie inside the frame) to the row's sums.
__attribute__((target_clones("avx2", "default"))) void AddTap(const AtrousPlanes& p, RowSums s, int width, int y,
                                                             int ny, int shift, int x0, int x1, float kernel_weight) {
  const std::size_t row = std::size_t(y) * width, neighbour_row = std::size_t(ny) * width + shift;
  const float *__restrict c_l = p.l + row, *__restrict c_depth = p.depth + row, *__restrict c_escaped = p.escaped + row;
  const float *__restrict c_coverage = p.coverage + row, *__restrict c_l_scale = p.l_scale + row;
  const float* __restrict c_z_scale = p.z_scale + row;
  const float *__restrict n_r = p.r + neighbour_row, *__restrict n_g = p.g + neighbour_row;
  const float *__restrict n_b = p.b + neighbour_row, *__restrict n_v = p.v + neighbour_row;
  const float *__restrict n_l = p.l + neighbour_row, *__restrict n_depth = p.depth + neighbour_row;
  const float *__restrict n_escaped = p.escaped + neighbour_row, *__restrict n_coverage = p.coverage + neighbour_row;
  float *__restrict s_r = s.r, *__restrict s_g = s.g, *__restrict s_b = s.b, *__restrict s_v = s.v;
  float* __restrict s_w = s.w;
  // The planes and sums never overlap; GCC does not take __restrict on
  // locals, and 10 run-time alias checks are its limit.
#pragma GCC ivdep
  for (int x = x0; x < x1; ++x) {
    // 0 where either ray escaped, as two selects (an || is a branch GCC
    // does not vectorise).
    const float depth_step = std::fabs(n_depth[x] - c_depth[x]);
    const float centre_hit = c_escaped[x] != 0.0f ? 0.0f : depth_step;
    const float dz = n_escaped[x] != 0.0f ? 0.0f : centre_hit;
    const float dc = std::fabs(n_coverage[x] - c_coverage[x]);
    const float w = kernel_weight * VectorisableExp(-std::fabs(n_l[x] - c_l[x]) * c_l_scale[x] - dz * c_z_scale[x] -
                                        dc * AtrousPass::kCoverageStop);
    s_r[x] += n_r[x] * w;
    s_g[x] += n_g[x] * w;
    s_b[x] += n_b[x] * w;
    s_v[x] += n_v[x] * w * w;
    s_w[x] += w;
  }
}

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
    const float z = pass.Depth(i);
    planes[0][i] = c.x;
    planes[1][i] = c.y;
    planes[2][i] = c.z;
    planes[3][i] = c.w;
    planes[4][i] = Luminance(Xyz(c));
    planes[5][i] = z;
    planes[6][i] = Escaped(pass.first_hit[i]) ? 1.0f : 0.0f;
    planes[7][i] = 1.0f / (pass.sigma_luminance * sqrtf(fmaxf(variance / vw, 0.0f)) + 1e-10f);
    planes[8][i] = 1.0f / (pass.sigma_depth * 0.01f * fmaxf(z, 1e-3f) * float(pass.step) + 1e-6f);
  }
}

constexpr int kPlanes = 9;

}  // namespace

void CpuAtrousLevel(const AtrousPass& pass) {
  const int w = pass.width, h = pass.height;
  const std::size_t n = std::size_t(w) * h;
  // Kept between calls (levels, frames): a level's planes are 36 bytes a
  // pixel. Calls from several threads (sessions) each have their own.
  thread_local std::vector<float> own_planes[kPlanes];
  std::vector<float>* const planes = own_planes;  // the helpers' own thread_local would be another
  for (int k = 0; k < kPlanes; ++k) planes[k].resize(n);
  ParallelFor(h, [&](std::int64_t y) { FillPlanes(pass, planes, int(y)); });
  const AtrousPlanes p{planes[0].data(), planes[1].data(), planes[2].data(), planes[3].data(), planes[4].data(),
                       planes[5].data(), planes[6].data(), pass.coverage,    planes[7].data(), planes[8].data()};
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
