// Per-pixel work of the baseline denoisers, host and device: progressive
// accumulation, Exposure Render's KNN filter, He et al.'s guided filter with
// the volume's guides, and SVGF (Schied et al. 2017) on our reprojection.
#pragma once

#include "core/sampling.h"
#include "denoise/denoiser.h"
#include "denoise/reprojection.h"

namespace cinevol {

// --- Progressive accumulation (reset on change) -----------------------------

struct AccumulatePass {
  const Vec3f* input;
  Vec3f* sum;        // running sum since the last reset
  Vec3f* output;     // running mean
  int width;
  float inv_frames;  // 1 / frames summed, this one included

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const Vec3f c = input[i];
    sum[i] += IsFinite(c) ? c : Vec3f{};
    output[i] = sum[i] * inv_frames;
  }
};

// --- Exposure Render's KNN filter -------------------------------------------

// Weights neighbours by colour distance (relative to the centre's luminance)
// and pixel distance, then fades towards the unfiltered mean as samples
// accumulate.
struct KnnPass {
  const Vec3f* mean;
  Vec3f* output;
  int width, height;
  KnnSettings s;
  float fade;  // 1: fully filtered, 0: unfiltered

  CINEVOL_HD void operator()(int x, int y) const {
    const Vec3f c = mean[y * width + x];
    const float scale = 1.0f / (Sqr(s.strength) * (Sqr(Luminance(c)) + 1e-8f));
    const float inv_r2 = 1.0f / float((s.radius + 1) * (s.radius + 1));
    Vec3f sum{};
    float weight = 0.0f;
    for (int dy = -s.radius; dy <= s.radius; ++dy) {
      for (int dx = -s.radius; dx <= s.radius; ++dx) {
        const int nx = x + dx, ny = y + dy;
        if (nx < 0 || ny < 0 || nx >= width || ny >= height) continue;
        const Vec3f n = mean[ny * width + nx];
        const Vec3f d = n - c;
        const float w = expf(-Dot(d, d) * scale - float(dx * dx + dy * dy) * inv_r2);
        sum += n * w;
        weight += w;
      }
    }
    output[y * width + x] = Lerp(c, sum / weight, fade);
  }
};

// --- Guided filter ------------------------------------------------------------

// The temporal feature (as wRLS's Eq. 12, without models) for the guide.
struct TemporalFeaturePass {
  ReprojectionView rv;
  const Vec3f* input;
  const Vec3f* prev_feature;
  Vec3f* feature;
  float alpha;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = rv.Index(x, y);
    const Vec3f c = IsFinite(input[i]) ? input[i] : Vec3f{};
    const Reprojection r = Reproject(rv, x, y);
    Vec3f history;
    feature[i] = r.valid && HistoryTaps(rv, r, rv.first_hit[i]).Sample(prev_feature, history)
                     ? history * alpha + c * (1.0f - alpha)
                     : c;
  }
};

// Per-pixel products the box filter averages: guide g = (log luminance of
// the feature, normalised depth), target n = the noisy colour.
struct GuidedMoments {
  float g0, g1, g00, g01, g11;
  Vec3f n, g0n, g1n;
};

CINEVOL_HD GuidedMoments operator+(const GuidedMoments& a, const GuidedMoments& b) {
  return {a.g0 + b.g0,   a.g1 + b.g1, a.g00 + b.g00, a.g01 + b.g01,
          a.g11 + b.g11, a.n + b.n,   a.g0n + b.g0n, a.g1n + b.g1n};
}
CINEVOL_HD GuidedMoments operator*(const GuidedMoments& a, float k) {
  return {a.g0 * k, a.g1 * k, a.g00 * k, a.g01 * k, a.g11 * k, a.n * k, a.g0n * k, a.g1n * k};
}

// The two guide channels of a pixel: log luminance of the temporal feature
// and the first-collision depth (in units of the eye's distance from the
// volume's centre; background pixels far behind).
struct GuideView {
  const Vec3f* feature;
  const Vec4f* first_hit;
  Camera camera;
  float depth_scale;

  CINEVOL_HD void At(int i, float& g0, float& g1) const {
    g0 = logf(Luminance(Max(feature[i], Vec3f{})) + 1e-4f);
    g1 = Escaped(first_hit[i]) ? 2.0f : Length(Xyz(first_hit[i]) - camera.eye) * depth_scale;
  }
};

struct GuidedMomentsPass {
  const Vec3f* input;
  GuideView guide;
  GuidedMoments* moments;
  int width;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    float g0, g1;
    guide.At(i, g0, g1);
    const Vec3f n = IsFinite(input[i]) ? input[i] : guide.feature[i];
    moments[i] = {g0, g1, g0 * g0, g0 * g1, g1 * g1, n, n * g0, n * g1};
  }
};

// Separable box mean of radius r along x (horizontal) or y.
template <class T>
struct BoxPass {
  const T* in;
  T* out;
  int width, height, radius;
  bool horizontal;

  CINEVOL_HD void operator()(int x, int y) const {
    T sum{};
    int count = 0;
    for (int d = -radius; d <= radius; ++d) {
      const int sx = horizontal ? x + d : x, sy = horizontal ? y : y + d;
      if (sx < 0 || sy < 0 || sx >= width || sy >= height) continue;
      sum = sum + in[sy * width + sx];
      ++count;
    }
    out[y * width + x] = sum * (1.0f / float(count));
  }
};

// Per-window linear model n = a . g + b (He et al.'s Eq. 8-9 with a 2-channel
// guide): a = (Sigma_g + eps)^-1 cov(g, n).
struct GuidedCoefficients {
  Vec3f a0, a1, b;
};

CINEVOL_HD GuidedCoefficients operator+(const GuidedCoefficients& a, const GuidedCoefficients& b) {
  return {a.a0 + b.a0, a.a1 + b.a1, a.b + b.b};
}
CINEVOL_HD GuidedCoefficients operator*(const GuidedCoefficients& a, float k) { return {a.a0 * k, a.a1 * k, a.b * k}; }

struct GuidedSolvePass {
  const GuidedMoments* mean;  // box means
  GuidedCoefficients* coefficients;
  int width;
  float eps0, eps1;

  CINEVOL_HD void operator()(int x, int y) const {
    const GuidedMoments& m = mean[y * width + x];
    const float s00 = m.g00 - m.g0 * m.g0 + eps0, s01 = m.g01 - m.g0 * m.g1, s11 = m.g11 - m.g1 * m.g1 + eps1;
    const float inv_det = 1.0f / fmaxf(s00 * s11 - s01 * s01, 1e-12f);
    const Vec3f c0 = m.g0n - m.n * m.g0, c1 = m.g1n - m.n * m.g1;  // cov(g, n)
    GuidedCoefficients k;
    k.a0 = (c0 * s11 - c1 * s01) * inv_det;
    k.a1 = (c1 * s00 - c0 * s01) * inv_det;
    k.b = m.n - k.a0 * m.g0 - k.a1 * m.g1;
    coefficients[y * width + x] = k;
  }
};

struct GuidedOutputPass {
  const GuidedCoefficients* mean;  // box means of the coefficients
  GuideView guide;
  Vec3f* output;
  int width;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    float g0, g1;
    guide.At(i, g0, g1);
    const GuidedCoefficients& k = mean[i];
    const Vec3f out = k.a0 * g0 + k.a1 * g1 + k.b;
    output[i] = IsFinite(out) ? Max(out, Vec3f{}) : guide.feature[i];
  }
};

// --- SVGF --------------------------------------------------------------------

struct SvgfHistory {
  Vec3f color;
  float moment1, moment2;  // of luminance
  float length;            // frames integrated
};

// Temporal accumulation of colour and luminance moments.
struct SvgfTemporalPass {
  ReprojectionView rv;
  const Vec3f* input;
  const SvgfHistory* prev;
  SvgfHistory* history;
  SvgfSettings s;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = rv.Index(x, y);
    const Vec3f c = IsFinite(input[i]) ? input[i] : Vec3f{};
    const float l = Luminance(c);
    const Reprojection r = Reproject(rv, x, y);
    SvgfHistory h{c, l, l * l, 1.0f};
    if (r.valid) {
      const SvgfHistory& p = prev[rv.Index(r.nx, r.ny)];
      if (IsFinite(p.color)) {
        h.length = fminf(p.length + 1.0f, 64.0f);
        const float ac = fmaxf(s.color_alpha, 1.0f / h.length), am = fmaxf(s.moments_alpha, 1.0f / h.length);
        h.color = Lerp(p.color, c, ac);
        h.moment1 = p.moment1 + (l - p.moment1) * am;
        h.moment2 = p.moment2 + (l * l - p.moment2) * am;
      }
    }
    history[i] = h;
  }
};

// Colour and variance: temporal variance once 4 frames are integrated, a 7x7
// spatial estimate before.
struct SvgfVariancePass {
  const SvgfHistory* history;
  const Vec4f* first_hit;
  Vec4f* color_variance;  // rgb colour, w variance
  int width, height;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const SvgfHistory& h = history[i];
    float variance = h.moment2 - h.moment1 * h.moment1;
    if (h.length < 4.0f) {
      float m1 = 0, m2 = 0, n = 0;
      for (int dy = -3; dy <= 3; ++dy) {
        for (int dx = -3; dx <= 3; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= width || ny >= height) continue;
          const int k = ny * width + nx;
          if (Escaped(first_hit[k]) != Escaped(first_hit[i])) continue;
          m1 += history[k].moment1;
          m2 += history[k].moment2;
          n += 1;
        }
      }
      variance = m2 / n - Sqr(m1 / n);
      variance *= 4.0f / h.length;  // fewer frames, less certain
    }
    color_variance[i] = ToVec4(h.color, fmaxf(variance, 0.0f));
  }
};

// What the a-trous levels stop at, once per frame (five levels read it):
// each pixel's depth, the distance from the eye to its nearest first hit
// (kEscapedDepth where every sample escaped), and its coverage, the share of
// the 5x5 window's pixels whose samples hit the volume. In semi-transparent
// tissue whether a pixel's few samples collide is itself random, so this
// share, not the pixel's own flag, tells a real silhouette (a jump from 0 to
// 1) from transparency (a noisy middle).
// kEscapedDepth is NaN: a depth difference with an escaped pixel is then NaN,
// which an a-trous tap's fmaxf drops (AtrousPass), with no test in the tap.
inline constexpr float kEscapedDepth = __builtin_nanf("");

// Both in one, since every a-trous tap reads both: one 8-byte load.
struct alignas(8) EdgeGuide {
  float depth, coverage;
};

// The coverage window's half width (5x5), and a pixel's tap in it: 1 where
// its samples hit the volume. The backend's RowWindowSums add the taps up
// along rows, EdgeGuidesPass down the columns: a pixel's first hit is read
// once, not 25 times.
inline constexpr int kCoverageRadius = 2;

struct HitTap {
  const Vec4f* first_hit;
  int width;
  CINEVOL_HD float operator()(int x, int y) const { return Escaped(first_hit[y * width + x]) ? 0.0f : 1.0f; }
};

struct EdgeGuidesPass {
  const Vec4f* first_hit;
  const float* row_hits;  // RowWindowSums of HitTap over kCoverageRadius
  Vec3f eye;
  EdgeGuide* guides;
  Vec4f* kept_first_hit;  // null, or where the first hits are copied on the way
  int width, height;

  CINEVOL_HD void operator()(int x, int y) const {
    float hits = 0.0f;
    int rows = 0;
    for (int dy = -kCoverageRadius; dy <= kCoverageRadius; ++dy) {
      const int ny = y + dy;
      if (ny < 0 || ny >= height) continue;
      hits += row_hits[ny * width + x];
      ++rows;
    }
    const int columns = MinInt(x + kCoverageRadius, width - 1) - MaxInt(x - kCoverageRadius, 0) + 1;
    const int i = y * width + x;
    const Vec4f hit = first_hit[i];
    guides[i] = {Escaped(hit) ? kEscapedDepth : Length(Xyz(hit) - eye), hits / float(rows * columns)};
    if (kept_first_hit) kept_first_hit[i] = hit;
  }
};

// The edge guides of a frame on backend B; `row_hits` is scratch of a
// frame's size. A temporal denoiser keeps the first hits for its next frame
// in `kept_first_hit` on the way (saving a copy): by then this frame's
// reprojection must be done with the previous ones.
template <class B>
void ComputeEdgeGuides(const Vec4f* first_hit, Vec3f eye, int width, int height, float* row_hits, EdgeGuide* guides,
                       Vec4f* kept_first_hit = nullptr) {
  B::RowWindowSums(width, height, kCoverageRadius, 1, HitTap{first_hit, width}, row_hits);
  B::ForEachPixel(width, height, EdgeGuidesPass{first_hit, row_hits, eye, guides, kept_first_hit, width, height});
}

// The a-trous taps every such filter shares (AtrousPass; the refinement's
// MeanFilterPass, pipeline/refine.h): 5x5 B-spline taps `step` apart around
// (x, y), each weighed by stop(k, q, log2_kernel): the kernel's weight
// (2^log2_kernel) times the edge stop for the neighbour at index k with
// colour and variance q (the stop folds the kernel into its exponent, one
// multiplication less a tap). The colour is averaged with the weights; the
// variance in w goes through with their squares.
// denoise/cpu_passes.h has the same taps as vectorised rows (CpuAtrousRows).
//
// On the GPU these levels are bound by instruction issue, not memory, so the
// taps are unrolled: away from the frame's edges without bounds checks, and
// for the levels' own steps (1 to 16) with the offsets known when compiled,
// so a tap's loads need no address arithmetic (kStep 0: `step` at run time).
// log2(e): the stops' exponentials are powers of 2, e^x = 2^(x log2(e)).
inline constexpr float kLog2e = 1.44269504088896341f;

template <int kStep, bool kChecked, class EdgeStop>
CINEVOL_HD Vec4f AtrousTapsUnrolled(const Vec4f* in, int x, int y, int width, int height, int step,
                                    const EdgeStop& stop) {
  if (kStep > 0) step = kStep;
  // log2 of 3/8, 1/4 and 1/16
  const float log2_kernel[3] = {-1.41503749927884381f, -2.0f, -4.0f};
  Vec3f sum{};
  float var_sum = 0.0f, weight = 0.0f;
  CINEVOL_UNROLL
  for (int dy = -2; dy <= 2; ++dy) {
    const int ny = y + dy * step;
    if (kChecked && (ny < 0 || ny >= height)) continue;
    const int row = ny * width + x;
    CINEVOL_UNROLL
    for (int dx = -2; dx <= 2; ++dx) {
      if (kChecked && (x + dx * step < 0 || x + dx * step >= width)) continue;
      const int k = row + dx * step;
      const Vec4f q = in[k];
      const float w = stop(k, q, log2_kernel[dx < 0 ? -dx : dx] + log2_kernel[dy < 0 ? -dy : dy]);
      sum += Xyz(q) * w;
      var_sum += q.w * w * w;
      weight += w;
    }
  }
  return ToVec4(sum / weight, var_sum / (weight * weight));
}

template <class EdgeStop>
CINEVOL_HD Vec4f AtrousTaps(const Vec4f* in, int x, int y, int width, int height, int step, const EdgeStop& stop) {
  const int reach = 2 * step;
  if (x < reach || y < reach || x + reach >= width || y + reach >= height) {
    return AtrousTapsUnrolled<0, true>(in, x, y, width, height, step, stop);
  }
  switch (step) {
    case 1: return AtrousTapsUnrolled<1, false>(in, x, y, width, height, step, stop);
    case 2: return AtrousTapsUnrolled<2, false>(in, x, y, width, height, step, stop);
    case 4: return AtrousTapsUnrolled<4, false>(in, x, y, width, height, step, stop);
    case 8: return AtrousTapsUnrolled<8, false>(in, x, y, width, height, step, stop);
    case 16: return AtrousTapsUnrolled<16, false>(in, x, y, width, height, step, stop);
    default: return AtrousTapsUnrolled<0, false>(in, x, y, width, height, step, stop);
  }
}

// One a-trous level (SVGF's, and wRLS's spatial stage): AtrousTaps stopped
// at coverage, depth and luminance edges (the last scaled by the local
// standard deviation). Depth compares only pixels that both hit.
struct AtrousPass {
  const Vec4f* in;
  Vec4f* out;
  const EdgeGuide* guides;  // EdgeGuidesPass
  int width, height, step;
  float sigma_luminance, sigma_depth;
  // The luminance stop's shape: SVGF's e^-(|dl| / (sigma dev)) (false), or
  // e^-(dl / (sigma dev))^2 (true), which cuts differences beyond sigma
  // deviations harder and keeps the noise-sized ones nearer to 1.
  bool squared_luminance = false;
  // Null, or the frame's scale of the variance the luminance stop reads
  // (StopCalibrationPass); the variance carried through the level is not scaled.
  const float* variance_scale = nullptr;
  // Null, or FrameTargets::surface_normal: taps also stop at e^-(normal_stop
  // (|a| |b| - a . b)) between the centre's a and the tap's b, surface
  // probability times normal each, so the stop acts only between surfaces
  // that both are and face different ways.
  const Vec3f* normals = nullptr;
  float normal_stop = 0.0f;

  CINEVOL_HD static bool Hit(float depth) { return !std::isnan(depth); }
  CINEVOL_HD float StopVariance(float variance) const {
    const float v = fmaxf(variance, 0.0f);
    return variance_scale ? v * *variance_scale : v;
  }

  // A full silhouette (coverage 0 against 1) weighs e^-6; the +-0.1 noise of
  // coverage in transparent tissue about e^-0.6.
  static constexpr float kCoverageStop = 6.0f;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    // Gaussian-blurred variance at the centre steadies the luminance stop
    // (the frame's edge pixels repeated beyond it).
    const int xs[3] = {MaxInt(x - 1, 0), x, MinInt(x + 1, width - 1)};
    const int ys[3] = {MaxInt(y - 1, 0), y, MinInt(y + 1, height - 1)};
    float variance = 0.0f;  // the weights sum to 1
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        variance += in[ys[r] * width + xs[c]].w * ((r == 1 ? 0.5f : 0.25f) * (c == 1 ? 0.5f : 0.25f));
      }
    }
    // The stops in powers of 2 (the GPU's native exponential): e^-(a + b +
    // c) = 2^-(a + b + c) log2(e); the centre tap weighs its kernel weight
    // alone (its differences are 0), so the sum of weights is never 0. A
    // pixel that escaped compares no depths: its depth is NaN (kEscapedDepth),
    // and so is the depth term, which fmaxf drops (for two hits the term is
    // >= 0, so fmaxf keeps it).
    const float l = Luminance(Xyz(in[i]));
    const float deviation = sigma_luminance * sqrtf(StopVariance(variance)) + 1e-10f;
    const float l_scale = (squared_luminance ? 1.0f : kLog2e) / deviation;
    const EdgeGuide centre = guides[i];
    const float z = centre.depth;
    const float z_scale = Hit(z) ? kLog2e / (sigma_depth * 0.01f * fmaxf(z, 1e-3f) * float(step) + 1e-6f) : 0.0f;
    const Vec3f n = normals ? normals[i] : Vec3f{};
    const float n_scale = normal_stop * kLog2e * Length(n);
    // Each tap's exponent is a chain of fused multiply-adds that starts from
    // the kernel's (-log2_kernel). The luminance is computed as l was, so
    // the centre's difference is exactly 0 whatever l_scale.
    out[i] = AtrousTaps(in, x, y, width, height, step, [&](int k, Vec4f q, float log2_kernel) {
      const EdgeGuide g = guides[k];
      const float dl = fabsf(Luminance(Xyz(q)) - l);
      const float e = squared_luminance ? fmaf(Sqr(dl * l_scale), kLog2e, -log2_kernel)
                                        : fmaf(dl, l_scale, -log2_kernel);
      const float ez = fmaxf(fmaf(fabsf(g.depth - z), z_scale, e), e);
      const float ec = fmaf(fabsf(g.coverage - centre.coverage), kCoverageStop * kLog2e, ez);
      if (!normals) return FastExp2(-ec);
      const Vec3f m = normals[k];
      return FastExp2(-(ec + fmaxf(n_scale * Length(m) - normal_stop * kLog2e * Dot(n, m), 0.0f)));
    });
  }
};

// --- The luminance stop's calibration (WrlsSettings::atrous_calibration_floor) --
//
// How far the variance the a-trous levels are given is from the spread it
// should predict, once a frame. Over horizontally adjacent pixels that both
// hit, r = dl^2 / (var_a + var_b) (their luminance difference against their
// two variances) is a chi-square of one degree where the variances are right
// and only noise differs, whose median is kChiSquareMedian; real detail only
// raises it. The frame's median of r over that median is the scale; the
// levels then stop at sigma deviations of the scaled variance
// (AtrousPass::variance_scale).
// The medians are counted in bins of log2 r (kCalibrationBinsPerOctave to
// an octave from 2^kCalibrationLowestLog2), the same on either backend.
inline constexpr int kCalibrationBins = 256;
inline constexpr float kCalibrationLowestLog2 = -12.0f, kCalibrationBinsPerOctave = 16.0f;
inline constexpr float kChiSquareMedian = 0.45493642f;
inline constexpr float kCalibrationHighest = 4.0f;  // the scale never loosens the stop more than this

// Every kCalibrationRowStep-th row is measured: a quarter of a 720p frame's
// pairs (about 230,000) pin the median to well within a bin (4% wide).
inline constexpr int kCalibrationRowStep = 4;

// B::CountInBins's bin of r at (x, row * kCalibrationRowStep), -1 where no
// pair is measured; over (width, CalibrationRows(height)).
CINEVOL_HD int CalibrationRows(int height) { return (height + kCalibrationRowStep - 1) / kCalibrationRowStep; }

struct StopCalibrationBin {
  const Vec4f* estimate;  // colour and variance, as the levels read them
  const EdgeGuide* guides;
  int width;
  CINEVOL_HD int operator()(int x, int row) const {
    if (x + 1 >= width) return -1;
    const int i = row * kCalibrationRowStep * width + x;
    if (!AtrousPass::Hit(guides[i].depth) || !AtrousPass::Hit(guides[i + 1].depth)) return -1;
    const Vec4f a = estimate[i], b = estimate[i + 1];
    const float variance = a.w + b.w;
    if (!(variance > 0.0f) || !isfinite(variance)) return -1;
    const float dl = Luminance(Xyz(a)) - Luminance(Xyz(b));
    const float r = dl * dl / variance;
    if (!isfinite(r)) return -1;  // NaN or infinite colour
    const float bin = (log2f(fmaxf(r, 1e-30f)) - kCalibrationLowestLog2) * kCalibrationBinsPerOctave;
    return int(fminf(fmaxf(bin, 0.0f), float(kCalibrationBins - 1)));
  }
};

// One thread: the median of the bins (interpolated within its bin) over
// kChiSquareMedian, kept within [floor, kCalibrationHighest] and, unless
// `fresh`, no lower than `fall` times the previous frame's scale (in *scale);
// 1 where no pair was measured. The bins are read in groups of
// kCalibrationGroup whose loads do not wait on each other (a walk of the
// bins one by one waits on each load in turn: 0.005 ms a frame more on an
// H100).
inline constexpr int kCalibrationGroup = 16;
struct StopCalibrationPass {
  const unsigned* bins;
  float* scale;
  float floor, fall;
  bool fresh;

  static constexpr int kGroups = kCalibrationBins / kCalibrationGroup;

  // The median's bin plus its place within the bin, given the groups' counts
  // (integers below 2^24: exact in float, summed in any order).
  CINEVOL_HD float MedianBin(const unsigned (&groups)[kGroups], unsigned total) const {
    const float half = 0.5f * float(total);
    float below = 0.0f;
    int g = 0;
    while (g + 1 < kGroups && below + float(groups[g]) < half) below += float(groups[g++]);
    unsigned counts[kCalibrationGroup];
    CINEVOL_UNROLL
    for (int k = 0; k < kCalibrationGroup; ++k) counts[k] = bins[g * kCalibrationGroup + k];
    int k = 0;
    while (k + 1 < kCalibrationGroup && below + float(counts[k]) < half) below += float(counts[k++]);
    const float within = counts[k] > 0 ? (half - below) / float(counts[k]) : 0.5f;
    return float(g * kCalibrationGroup + k) + within;
  }

  CINEVOL_HD void operator()(int, int) const {
    unsigned groups[kGroups], total = 0;
    CINEVOL_UNROLL
    for (int g = 0; g < kGroups; ++g) {
      groups[g] = 0;
      CINEVOL_UNROLL
      for (int k = 0; k < kCalibrationGroup; ++k) groups[g] += bins[g * kCalibrationGroup + k];
      total += groups[g];
    }
    const float ratio = total > 0
        ? exp2f(kCalibrationLowestLog2 + MedianBin(groups, total) / kCalibrationBinsPerOctave) / kChiSquareMedian
        : 1.0f;
    const float kept = fresh ? ratio : fmaxf(ratio, fall * *scale);
    *scale = fminf(fmaxf(kept, floor), kCalibrationHighest);
  }
};

// --- Demodulation -------------------------------------------------------------

inline constexpr float kAlbedoFloor = 1e-3f;

struct DemodulatePass {
  const Vec3f* input;
  const Vec3f* albedo;
  Vec3f* output;
  int width;
  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    output[i] = input[i] / Max(albedo[i], Vec3f{kAlbedoFloor, kAlbedoFloor, kAlbedoFloor});
  }
};

struct RemodulatePass {
  const Vec3f* albedo;
  Vec3f* image;
  int width;
  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    image[i] *= Max(albedo[i], Vec3f{kAlbedoFloor, kAlbedoFloor, kAlbedoFloor});
  }
};

// Copies the input, non-finite pixels zeroed.
struct CopyPass {
  const Vec3f* in;
  Vec3f* out;
  int width;
  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    out[i] = IsFinite(in[i]) ? in[i] : Vec3f{};
  }
};

// Copies the colour of a colour+variance image.
struct ColorOfPass {
  const Vec4f* in;
  Vec3f* out;
  int width;
  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const Vec3f c = Xyz(in[i]);
    out[i] = IsFinite(c) ? Max(c, Vec3f{}) : Vec3f{};
  }
};

}  // namespace cinevol
