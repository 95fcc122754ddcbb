// The wRLS denoiser's per-pixel work (Iglesias-Guitian et al., Sec. 5-6),
// host and device.
//
// Per pixel: a temporal feature z (Eq. 12; its reprojected history first
// rescaled by the window's change of light, FeatureRatioTap), then per
// channel a linear model I ~ beta0 + beta1 z updated by weighted recursive
// least squares (Eqs. 9-11, 13, 14); a second pass evaluates each pixel's
// model, with the variance it predicts; after the a-trous levels (baselines.h) a last pass
// steadies the output over time.
//
// Numerics (what keeps it stable at the extremes):
// - Each model works in units of its own scale s (the feature's magnitude
//   when it was made): predictor p = [1, z/s], target I/s. Radiance from 1e-4
//   to 1e4, or an exposure change of 1e8, gives the same numbers. When z
//   drifts 16x away from s the model is rescaled exactly.
// - The gain is q = w P p / (lambda + w p'Pp): w is never a divisor, so a
//   weight of 0 (an outlier) is a no-op rather than a division by zero.
// - P is stored symmetric (three numbers) and updated in the symmetric form
//   P' = (P - k k' w / (lambda + w p'k)) / lambda with k = P p.
// - On a static view only one direction of p is excited and P grows as
//   lambda^-n in the other (x5e8 after 10,000 frames at 0.998); its trace is
//   scaled back to max_trace_p, so the next camera move cannot spike.
// - A model resets on disocclusion, failed reprojection, non-finite numbers,
//   a non-positive-definite P or a coefficient beyond max_coefficient.
#pragma once

#include <cstdint>
#include <cstring>

#include "core/sampling.h"
#include "denoise/baselines.h"
#include "denoise/denoiser.h"
#include "denoise/reprojection.h"

namespace cinevol {

// One pixel's three per-channel models. Aligned to 16 bytes (80 a pixel, 76
// of them used): the GPU then reads and writes a model as five 16-byte
// accesses instead of nineteen 4-byte ones.
struct alignas(16) WrlsModel {
  float scale = 0;    // s
  Vec3f beta0, beta1; // I/s = beta0 + beta1 z/s, per channel
  Vec3f p00, p01, p11;  // P per channel (symmetric 2x2)
  // Weighted mean square of the luminance residual (sample - prediction), in
  // units of s^2: the noise the fit sees. < 0 until the first sample.
  float residual = -1;
  // How many samples' worth the feature z holds (its variance is the
  // samples' over this): 1 for a fresh pixel, (1 + alpha) / (1 - alpha) for
  // the paper's moving average, growing with every frame of a still view.
  float samples = 0;
  // Running mean of the signed luminance residual, in units of s: near 0
  // while the model predicts, drifting when the radiance changes under it.
  float drift = 0;
};

inline constexpr float kWrlsMinScale = 1e-20f;

// IEEE half precision (round to nearest, ties to even), host and device:
// the GPU's conversion instructions, and the same rounding in software.
CINEVOL_HD std::uint16_t ToHalf(float f) {
#ifdef __CUDA_ARCH__
  std::uint16_t h;
  asm("cvt.rn.f16.f32 %0, %1;" : "=h"(h) : "f"(f));
  return h;
#else
  std::uint32_t x;
  std::memcpy(&x, &f, sizeof x);
  const std::uint32_t sign = (x >> 16) & 0x8000u;
  x &= 0x7fffffffu;
  if (x >= 0x7f800000u) return std::uint16_t(sign | (x > 0x7f800000u ? 0x7e00u : 0x7c00u));  // NaN, infinity
  if (x >= 0x477ff000u) return std::uint16_t(sign | 0x7c00u);  // rounds to 65520 or more: infinity
  std::uint32_t h, rest, half_step;
  if (x >= 0x38800000u) {  // normal
    h = (x - 0x38000000u) >> 13;
    rest = x & 0x1fffu;
    half_step = 0x1000u;
  } else {  // a subnormal half (or 0): the significand shifted to units of 2^-24
    if (x < 0x33000000u) return std::uint16_t(sign);
    const std::uint32_t significand = (x & 0x7fffffu) | 0x800000u, shift = 126u - (x >> 23);
    h = significand >> shift;
    rest = significand & ((1u << shift) - 1u);
    half_step = 1u << (shift - 1u);
  }
  h += rest > half_step || (rest == half_step && (h & 1u));
  return std::uint16_t(sign | h);
#endif
}

CINEVOL_HD float FromHalf(std::uint16_t h) {
#ifdef __CUDA_ARCH__
  float f;
  asm("cvt.f32.f16 %0, %1;" : "=f"(f) : "h"(h));
  return f;
#else
  const std::uint32_t sign = std::uint32_t(h & 0x8000u) << 16, exponent = (h >> 10) & 0x1fu, mantissa = h & 0x3ffu;
  if (exponent == 0) {  // 0 or subnormal: exact in single precision
    const float v = float(mantissa) * 5.9604644775390625e-8f;  // 2^-24
    return sign ? -v : v;
  }
  const std::uint32_t x = sign | (exponent == 31 ? 0x7f800000u | (mantissa << 13) : ((exponent + 112u) << 23) | (mantissa << 13));
  float f;
  std::memcpy(&f, &x, sizeof f);
  return f;
#endif
}

// A model as stored between frames: 64 bytes, four 16-byte accesses on the
// GPU. beta0 and beta1 are kept in half precision (they are bounded by
// max_coefficient, 1e4, within its range); P must stay single precision
// (half costs 0.4-0.8 dB, docs/performance.md).
struct alignas(16) StoredWrlsModel {
  float scale, residual, samples, drift;
  Vec3f p00, p01, p11;
  std::uint16_t beta0[3], beta1[3];
};
static_assert(sizeof(StoredWrlsModel) == 64);

CINEVOL_HD StoredWrlsModel Store(const WrlsModel& m) {
  StoredWrlsModel s{m.scale, m.residual, m.samples, m.drift, m.p00, m.p01, m.p11, {}, {}};
  for (int c = 0; c < 3; ++c) {
    s.beta0[c] = ToHalf(m.beta0[c]);
    s.beta1[c] = ToHalf(m.beta1[c]);
  }
  return s;
}

CINEVOL_HD WrlsModel Load(const StoredWrlsModel& s) {
  WrlsModel m;
  m.scale = s.scale;
  m.residual = s.residual;
  m.samples = s.samples;
  m.drift = s.drift;
  m.p00 = s.p00;
  m.p01 = s.p01;
  m.p11 = s.p11;
  for (int c = 0; c < 3; ++c) {
    m.beta0[c] = FromHalf(s.beta0[c]);
    m.beta1[c] = FromHalf(s.beta1[c]);
  }
  return m;
}

CINEVOL_HD float MeanComponent(Vec3f v) { return (v.x + v.y + v.z) * (1.0f / 3.0f); }

// A fresh model predicting the feature itself (beta = [0, 1]).
CINEVOL_HD WrlsModel InitialModel(Vec3f z, float initial_p) {
  WrlsModel m;
  m.scale = fmaxf(MeanComponent(Abs(z)), kWrlsMinScale);
  m.beta0 = {0, 0, 0};
  m.beta1 = {1, 1, 1};
  m.p00 = m.p11 = {initial_p, initial_p, initial_p};
  m.p01 = {0, 0, 0};
  m.residual = -1;
  m.samples = 0;
  m.drift = 0;
  return m;
}

// Starts the fit afresh at feature z; what the model knows of the feature
// (its samples and their noise) stays.
CINEVOL_HD void Refit(WrlsModel& m, Vec3f z, float initial_p) {
  const float samples = m.samples, residual = m.residual;
  m = InitialModel(z, initial_p);
  m.samples = isfinite(samples) ? samples : 0.0f;
  m.residual = isfinite(residual) ? residual : -1.0f;
}

CINEVOL_HD bool Healthy(const WrlsModel& m, float max_coefficient) {
  if (!(m.scale >= kWrlsMinScale) || !isfinite(m.scale)) return false;
  for (int c = 0; c < 3; ++c) {
    const float b0 = m.beta0[c], b1 = m.beta1[c], a = m.p00[c], b = m.p01[c], d = m.p11[c];
    if (!(fabsf(b0) <= max_coefficient && fabsf(b1) <= max_coefficient)) return false;  // also NaN
    if (!(a > 0.0f && d > 0.0f && a * d - b * b > 0.0f) || !isfinite(a + b + d)) return false;
  }
  return true;
}

// A noise estimate (residual) in a model's units: it overflows where the
// model is black (scale at the floor, 1e-20) and its neighbourhood or its
// next, lit frame is not; such an estimate reads as no noise seen (0), as a
// black pixel's own samples show none, and the model learns its noise from
// its next samples. Left infinite, the next update made it a NaN that froze
// the model's noise at "none" for as long as the pixel kept its history
// (about 1% of a 2-spp frame's pixels, docs/tradeoff.md).
CINEVOL_HD float FiniteResidual(float residual) { return isfinite(residual) ? residual : 0.0f; }

// Re-expresses the model in units of `scale`: its predictions are exact.
// P is not re-expressed exactly (that would divide p01 by r and p11 by r^2):
// scaled as below, a model that brightens by more than 16 times keeps a firm
// prior on its slope rather than forgetting it. The exact P, which lets a
// model lit after black fit its slope to one noisy sample, cost 0.1-0.7 dB
// (docs/tradeoff.md, "A black pixel's noise").
CINEVOL_HD void Rescale(WrlsModel& m, float scale) {
  const float r = m.scale / scale;
  m.beta0 *= r;
  m.p01 *= r;
  m.p11 *= r * r;
  if (m.residual > 0) m.residual = FiniteResidual(m.residual * r * r);
  m.drift *= r;
  m.scale = scale;
}

// Variance of the model's prediction at feature z (radiance^2), from the
// residual variance the fit sees: the feature's noise carried by the slope
// (beta1^2 / samples) plus the fit's own uncertainty (p'Pp), averaged over
// channels.
// A young model's variance is raised to young_variance / samples^2 times its
// noise (SVGF's 4 / frames in spirit): a firm prior (small P) would otherwise
// predict little variance for a model that has seen one or two samples.
CINEVOL_HD float PredictionVariance(const WrlsModel& m, Vec3f z, float young_variance) {
  if (!(m.residual >= 0.0f) || !(m.samples >= 1.0f)) return 0.0f;
  const float inv = 1.0f / m.scale;
  float sum = 0.0f;
  for (int c = 0; c < 3; ++c) {
    const float u = z[c] * inv;
    sum += m.beta1[c] * m.beta1[c] / m.samples + m.p00[c] + 2.0f * m.p01[c] * u + m.p11[c] * u * u;
  }
  return m.residual * fmaxf(sum * (1.0f / 3.0f), young_variance / (m.samples * m.samples)) * m.scale * m.scale;
}

// The young-variance floor of a pixel whose edge guide reads `coverage`
// (WrlsSettings::young_variance_surface).
CINEVOL_HD float YoungVariance(const WrlsSettings& s, float coverage) {
  return s.young_variance_surface >= 0.0f && coverage >= 1.0f ? s.young_variance_surface : s.young_variance;
}

// Eq. 13's weight of a sample: its distance from the feature, relative to
// the feature. The paper divides by min(|sample|, |z|), which weighs a
// sample below the feature less than one as far above it, and the fit leans
// bright: +1.4% radiance on the MR head at 720p, +1.6% on CThead, +2.6% on
// the phantom's orbit (RenderedSequence test), which put wRLS 1.3 dB behind
// SVGF on the MR head. Relative to the stable feature the level stays within
// 0.3% on those (-0.9% on the aorta crop, SVGF -0.6%) and wRLS leads SVGF
// on every scenario of the study (docs/tradeoff.md, "The MR gap at 720p").
CINEVOL_HD float SampleWeight(Vec3f sample, Vec3f z, float bandwidth, float epsilon) {
  const float d = Length(sample - z) / (Length(z) + epsilon);
  return expf(-(d * d) / (bandwidth * bandwidth));
}

// One weighted RLS step for channel c with predictor [1, u] and target y.
CINEVOL_HD void UpdateChannel(WrlsModel& m, int c, float u, float y, float w, const WrlsSettings& s) {
  float a = m.p00[c], b = m.p01[c], d = m.p11[c];
  const float k0 = a + b * u, k1 = b + d * u;  // k = P p
  const float denom = s.lambda + w * (k0 + k1 * u);  // lambda + w p'Pp (> 0: P is positive definite)
  const float error = y - (m.beta0[c] + m.beta1[c] * u);
  const float g = w / denom;  // gain q = g k
  m.beta0[c] += g * k0 * error;
  m.beta1[c] += g * k1 * error;
  const float inv_lambda = 1.0f / s.lambda;
  a = (a - g * k0 * k0) * inv_lambda;
  b = (b - g * k0 * k1) * inv_lambda;
  d = (d - g * k1 * k1) * inv_lambda;
  const float trace = a + d;
  if (trace > s.max_trace_p) {
    const float shrink = s.max_trace_p / trace;
    a *= shrink;
    b *= shrink;
    d *= shrink;
  }
  m.p00[c] = a;
  m.p01[c] = b;
  m.p11[c] = d;
}

// Forgetting that adapts to how well the model predicts (WrlsSettings::
// drift_sigma): while the running mean of the residual stays within
// drift_sigma deviations of what noise alone gives it, the model keeps its
// firm prior; when it drifts beyond them (the radiance changed under the
// model), P is widened by kWrlsDriftBoost, so the next samples move the fit.
// A model with no noise estimate yet (residual 0) waits: every error would
// read as a drift (at 1 spp on the MR head's still view at 720p such false
// alarms cost 1.8 dB, docs/tradeoff.md).
inline constexpr float kWrlsDriftRate = 0.3f;  // EMA rate of the drift: a change shows within 2-3 frames
// What a drift adds to P's diagonal: 3 (with drift_sigma 1.5) read the same
// to 0.02 dB, since the drift rarely fires.
inline constexpr float kWrlsDriftBoost = 1.0f;

CINEVOL_HD void AdaptForgetting(WrlsModel& m, float luminance_error, float w, const WrlsSettings& s) {
  if (!(m.residual > 0.0f)) return;
  m.drift += kWrlsDriftRate * w * (luminance_error - m.drift);
  // An EMA of rate k over noise of variance v has variance v k / (2 - k).
  const float noise = m.residual * (kWrlsDriftRate / (2.0f - kWrlsDriftRate));
  if (Sqr(m.drift) <= Sqr(s.drift_sigma) * noise) return;
  const Vec3f boost{kWrlsDriftBoost, kWrlsDriftBoost, kWrlsDriftBoost};
  m.p00 += boost;
  m.p11 += boost;
  m.drift = 0.0f;
}

// wRLS's two histories, the previous frame's feature and its stabilised
// output, reprojected to this frame in one pass (one reprojection a pixel):
// rgb, and w = 1 where it could be (0 on disocclusion). It also keeps each
// pixel's nearest previous pixel (-1: none), whose model the temporal pass
// continues.
struct ReprojectHistoriesPass {
  ReprojectionView rv;
  const Vec3f* previous_feature;
  const Vec3f* previous_output;
  Vec4f* feature_history;
  Vec4f* output_history;
  int* previous_pixel;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = rv.Index(x, y);
    const Reprojection r = Reproject(rv, x, y);
    const Vec4f hit = rv.first_hit[i];
    Vec3f f, o;
    bool has_f = false, has_o = false;
    if (r.valid) {
      const HistoryTaps taps(rv, r, hit);
      has_f = taps.Sample(previous_feature, f) && IsFinite(f);
      has_o = taps.Sample(previous_output, o) && IsFinite(o);
    }
    feature_history[i] = has_f ? ToVec4(f, 1.0f) : Vec4f{};
    output_history[i] = has_o ? ToVec4(o, 1.0f) : Vec4f{};
    previous_pixel[i] = r.valid ? rv.Index(r.nx, r.ny) : -1;
  }
};

// The stabiliser's recentering (WrlsSettings::stabilize_recenter): the
// history is shifted by its mean offset from the estimate over (2 recenter +
// 1)^2 taps 2 pixels apart. A change of shading moves a whole region the same
// way and is taken out of the history (no lag), while noise, different from
// pixel to pixel, mostly averages away in the window. A tap is a pixel's
// history - estimate, and in w 1, where it was reprojected (0 elsewhere):
// the backend's RowWindowSums add them up along rows, WindowMean down the
// columns, so the window costs 2 (2 recenter + 1) reads.
struct HistoryOffsetTap {
  const Vec4f* current;  // this frame's estimate
  const Vec4f* history;  // ReprojectHistoriesPass's output history
  int width;

  CINEVOL_HD Vec4f operator()(int x, int y) const {
    const int k = y * width + x;
    if (history[k].w == 0.0f) return {};
    return ToVec4(Xyz(history[k]) - Xyz(current[k]), 1.0f);
  }
};

// The feature's rescaling (WrlsSettings::feature_rescale): as the
// stabiliser's recentering, but a ratio, since a light changes radiance in
// proportion (dark and bright tissue in one window brighten by the same
// factor). A tap is the luminance of the history (x) and of the input (y)
// and 1 (w) where the history was reprojected. An input tap counts at most
// firefly_clamp times its history, so a firefly does not scale the window.
struct FeatureRatioTap {
  const Vec3f* input;
  const Vec4f* history;  // ReprojectHistoriesPass's feature history
  int width;
  float firefly_clamp;

  CINEVOL_HD Vec4f operator()(int x, int y) const {
    const int k = y * width + x;
    if (history[k].w == 0.0f || !IsFinite(input[k])) return {};
    const float h = Luminance(Xyz(history[k]));
    return {h, fminf(fmaxf(Luminance(input[k]), 0.0f), firefly_clamp * h), 0.0f, 1.0f};
  }
};

// The row sums of the window taps above are 2 pixels apart.
inline constexpr int kWindowTapStride = 2;

// Row sums of HistoryOffsetTap or FeatureRatioTap added up over the
// column's taps: the window's mean of what the rows summed, and in w over how
// many pixels.
CINEVOL_HD Vec4f WindowMean(const Vec4f* rows, int width, int height, int x, int y, int radius) {
  Vec3f sum{};
  float n = 0.0f;
  for (int dy = -radius; dy <= radius; ++dy) {
    const int ny = y + kWindowTapStride * dy;
    if (ny < 0 || ny >= height) continue;
    const Vec4f row = rows[ny * width + x];
    sum += Xyz(row);
    n += row.w;
  }
  return ToVec4(n > 0.0f ? sum / n : Vec3f{}, n);
}

// Each pixel's model evaluated at its feature, with the variance it
// predicts: rgb and w. The paper's blend of the neighbours' predictions (Sec.
// 5.3) measured 2.0 dB worse on the CThead orbit at 720p, and evaluating the
// neighbours' models at the centre's feature (its other reading) 1.1 dB worse
// still (docs/denoising.md): the a-trous levels do the spatial work.
CINEVOL_HD Vec4f Prediction(const WrlsModel& m, Vec3f z, float young_variance) {
  if (!IsFinite(z)) return ToVec4(z, 0.0f);
  const Vec3f out = m.beta0 * m.scale + m.beta1 * z;
  const float v = PredictionVariance(m, z, young_variance);
  return ToVec4(IsFinite(out) ? Max(out, Vec3f{}) : z, isfinite(v) ? v : 0.0f);
}

// Pass 1: the temporal feature, the model update and the model's prediction
// (Prediction), per pixel.
struct WrlsTemporalPass {
  ReprojectionView rv;
  const Vec3f* input;          // this frame's noisy radiance
  const Vec4f* prev_feature;   // z of the previous frame, reprojected (ReprojectHistoriesPass)
  const int* previous_pixel;   // ReprojectHistoriesPass
  const StoredWrlsModel* prev_model;
  Vec3f* feature;              // z of this frame
  StoredWrlsModel* model;
  Vec4f* prediction;           // the model at z: rgb, w its variance
  WrlsSettings s;
  int still_frames;            // frames the view has stayed still (0: it moved or changed)
  const Vec4f* feature_ratio_rows;  // row sums of FeatureRatioTap; null: no rescaling
  const EdgeGuide* guides;          // this frame's, where young_variance_surface is on (else null)

  // The finite inputs of the 3x3 window: their colour box, and the sum and
  // count of the centre's neighbours' brightest channel.
  struct Neighbourhood {
    Vec3f lo{3.4e38f, 3.4e38f, 3.4e38f}, hi{-3.4e38f, -3.4e38f, -3.4e38f};
    float level_sum = 0.0f;
    int count = 0;
  };

  // Unrolled; kChecked tests each tap against the frame's edges (a pixel on
  // them), which a pixel inside skips.
  template <bool kChecked>
  CINEVOL_HD Neighbourhood Neighbours(int x, int y) const {
    Neighbourhood n;
    CINEVOL_UNROLL
    for (int dy = -1; dy <= 1; ++dy) {
      CINEVOL_UNROLL
      for (int dx = -1; dx <= 1; ++dx) {
        if (kChecked && !rv.InBounds(x + dx, y + dy)) continue;
        const Vec3f c = input[rv.Index(x + dx, y + dy)];
        if (!IsFinite(c)) continue;
        n.lo = Min(n.lo, c);
        n.hi = Max(n.hi, c);
        if (dx != 0 || dy != 0) {
          n.level_sum += MaxComponent(c);
          ++n.count;
        }
      }
    }
    return n;
  }

  // Variance of the input's luminance over the 7x7 window (SVGF's first
  // estimate too): a 3x3 window at 2 spp misjudges the noise by 2x either way,
  // and the first frames' a-trous levels stop on it.
  // The window is clamped to the frame once, not tested tap by tap, and a tap
  // counts where its luminance is finite (so are its channels then).
  CINEVOL_HD float LocalLuminanceVariance(int x, int y) const {
    const int x0 = MaxInt(x - 3, 0), x1 = MinInt(x + 3, rv.width - 1);
    const int y0 = MaxInt(y - 3, 0), y1 = MinInt(y + 3, rv.height - 1);
    float sum = 0.0f, sum_sq = 0.0f, n = 0.0f;
    for (int ny = y0; ny <= y1; ++ny) {
      for (int nx = x0; nx <= x1; ++nx) {
        const float l = Luminance(input[rv.Index(nx, ny)]);
        if (!isfinite(l)) continue;
        sum += l;
        sum_sq += l * l;
        n += 1.0f;
      }
    }
    return n > 1.0f ? fmaxf(sum_sq / n - Sqr(sum / n), 0.0f) : 0.0f;
  }

  // The feature's history scaled by the window's ratio of input to history
  // luminance (WrlsSettings::feature_rescale), shrunk where that ratio is
  // within the noise of a mean over the window (Wiener: d^2 / (d^2 + k^2
  // var / n), d the ratio's distance from 1, var the model's residual
  // relative to the window's level): a real change is taken out whole, the
  // window's own noise, which the a-trous levels could not remove (it is
  // smooth), mostly not.
  CINEVOL_HD Vec3f Rescaled(Vec3f history, int x, int y, const WrlsModel& m) const {
    const Vec4f window = WindowMean(feature_ratio_rows, rv.width, rv.height, x, y, s.feature_rescale);
    if (!(window.x > 0.0f)) return history;
    const float ratio = window.y / window.x;
    const float signal = Sqr(ratio - 1.0f);
    const float noise = Sqr(s.feature_rescale_sigma * m.scale / window.x) * fmaxf(m.residual, 0.0f) / window.w;
    const float keep = signal + noise > 0.0f ? signal / (signal + noise) : 0.0f;
    return history * (1.0f + keep * (ratio - 1.0f));
  }

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = rv.Index(x, y);
    const Vec3f sample = input[i];
    const bool sample_ok = IsFinite(sample);
    // The 3x3 neighbourhood: its colour box rectifies the history; the mean
    // level of the centre's neighbours (with the history) caps what a firefly
    // can add to z.
    const bool inside = x > 0 && y > 0 && x + 1 < rv.width && y + 1 < rv.height;
    const Neighbourhood around = inside ? Neighbours<false>(x, y) : Neighbours<true>(x, y);
    const int p = previous_pixel[i];
    const WrlsModel previous = p >= 0 ? Load(prev_model[p]) : WrlsModel{};
    const bool has_history = p >= 0 && prev_feature[i].w != 0.0f;
    Vec3f history = Xyz(prev_feature[i]);
    // A still view's history is exact: it is not rectified, and it weighs as
    // many samples as it holds, so z becomes the running mean.
    const bool still = still_frames > 0 && has_history;
    if (has_history && !still && feature_ratio_rows) history = Rescaled(history, x, y, previous);
    if (has_history && !still && around.lo.x <= around.hi.x) history = Min(Max(history, around.lo), around.hi);

    const float level = fmaxf(around.count > 0 ? around.level_sum / float(around.count) : 0.0f,
                              has_history ? MaxComponent(history) : 0.0f);
    const float cap = s.firefly_clamp * level;
    Vec3f entering = sample_ok ? Min(Max(sample, Vec3f{}), Vec3f{cap, cap, cap}) : Vec3f{};
    if (!sample_ok && has_history) entering = history;

    WrlsModel m = p >= 0 ? previous : InitialModel(entering, s.initial_p);
    if (!Healthy(m, s.max_coefficient)) Refit(m, entering, s.initial_p);
    // Eq. 12, all three channels together, with the sample's share starting
    // as a running mean (1, 1/2, 1/3, ...) down to the paper's 1 - alpha, or
    // on down to 1 / max_still_frames while the view stays still.
    const float held = has_history ? m.samples : 0.0f;
    const float floor_share = still ? 1.0f / float(s.max_still_frames > 1 ? s.max_still_frames : 1) : 1.0f - s.alpha;
    const float share = fmaxf(1.0f / (held + 1.0f), floor_share);
    const Vec3f z = has_history ? history * (1.0f - share) + entering * share : entering;
    feature[i] = z;
    // Exact variance bookkeeping: z = (1 - a) h + a x, var(h) = v / held.
    m.samples = held > 0.0f ? 1.0f / (Sqr(1.0f - share) / held + Sqr(share)) : 1.0f;
    const float magnitude = MeanComponent(Abs(z));
    if (magnitude > 16.0f * m.scale || magnitude * 16.0f < m.scale) Rescale(m, fmaxf(magnitude, kWrlsMinScale));

    if (sample_ok) {
      const float w = SampleWeight(sample, z, s.bandwidth, 1e-3f * m.scale);
      const float inv_scale = 1.0f / m.scale;
      Vec3f error;
      for (int c = 0; c < 3; ++c) error[c] = sample[c] * inv_scale - (m.beta0[c] + m.beta1[c] * z[c] * inv_scale);
      if (m.residual < 0.0f) {
        // A fresh model has seen nothing yet: its first estimate of the noise
        // is the neighbourhood's luminance variance.
        m.residual = FiniteResidual(LocalLuminanceVariance(x, y) * inv_scale * inv_scale);
      } else if (w > 0.0f) {  // a sample of no weight tells nothing (and its error may be out of range)
        AdaptForgetting(m, Luminance(error), w, s);
        m.residual += s.residual_rate * w * (Sqr(Luminance(error)) - m.residual);
      }
      for (int c = 0; c < 3; ++c) UpdateChannel(m, c, z[c] * inv_scale, sample[c] * inv_scale, w, s);
      if (!Healthy(m, s.max_coefficient)) Refit(m, z, s.initial_p);
    }
    model[i] = Store(m);
    prediction[i] = Prediction(m, z, guides ? YoungVariance(s, guides[i].coverage) : s.young_variance);
  }
};

// The normal stop's guide (WrlsSettings::atrous_normal_share < 1): this
// frame's surface normals blended into the previous guide at the pixel's
// nearest previous pixel, so the guide holds still from frame to frame, and
// where the normals disagree from frame to frame (soft tissue) the average
// shortens and the stop weakens by itself.
struct NormalGuidePass {
  const Vec3f* current;       // FrameTargets::surface_normal
  const Vec3f* previous;      // the previous frame's guide
  const int* previous_pixel;  // ReprojectHistoriesPass's (-1: none)
  Vec3f* guide;
  int width;
  float share;  // of this frame's normals

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const int p = previous_pixel[i];
    guide[i] = p >= 0 ? Lerp(previous[p], current[i], share) : current[i];
  }
};

// A pixel whose content moved less than this on screen stayed where it was.
constexpr float kUnmovedPixels = 0.5f;

// Pass 3, after the a-trous levels: temporal stabilisation of the output
// (WrlsSettings::stabilize_*). The history is clipped to this frame's estimate +- clamp_sigma deviations
// (Salvi's variance clipping; the deviation counts the 3x3 spread and the
// variance the fit predicts), so a real change (a light moving, the transfer
// function edited) passes through and only noise is averaged. The box is
// centred on the pixel, not on the 3x3 mean, so that it does not blur edges.
// The history is first recentred on the estimate (HistoryOffsetTap), so
// a change of shading passes whole and noise keeps being smoothed; but not
// where only the camera moved and what the pixel shows stayed on it: its
// history is then its own, and its shift from the estimate is noise.
struct WrlsStabilizePass {
  const Vec4f* current;      // this frame's estimate: colour, predicted variance
  const Vec4f* history;      // ReprojectHistoriesPass's output history
  const Vec4f* offset_rows;  // row sums of HistoryOffsetTap; null: not recentred (a still view)
  ReprojectionView view;     // its cameras and first hits tell a pixel's motion
  bool only_moved;           // DenoiseFrame::only_moved, and unmoved pixels are not recentred
  Vec3f* output;             // the denoiser's output
  Vec3f* kept;               // the same, kept as the next frame's history (may be `output`)
  int width, height;
  float history_weight, clamp_sigma;
  int recenter;  // >= 1

  CINEVOL_HD bool InBounds(int x, int y) const { return x >= 0 && y >= 0 && x < width && y < height; }

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const Vec3f c = Xyz(current[i]);
    Vec3f out = c;
    if (history[i].w != 0.0f) {
      Vec3f h = Xyz(history[i]);
      if (offset_rows && !(only_moved && ScreenMotion(view, x, y) < kUnmovedPixels)) {
        h = Max(h - Xyz(WindowMean(offset_rows, width, height, x, y, recenter)), Vec3f{});
      }
      Vec3f sum{}, sum_sq{};
      float n = 0.0f;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          if (!InBounds(x + dx, y + dy)) continue;
          const Vec3f q = Xyz(current[(y + dy) * width + x + dx]);
          sum += q;
          sum_sq += q * q;
          n += 1.0f;
        }
      }
      const Vec3f mean = sum / n;
      const float predicted = fmaxf(current[i].w, 0.0f);
      Vec3f deviation;
      for (int k = 0; k < 3; ++k) {
        deviation[k] = clamp_sigma * sqrtf(fmaxf(sum_sq[k] / n - mean[k] * mean[k], 0.0f) + predicted);
      }
      out = Lerp(c, Min(Max(h, c - deviation), c + deviation), history_weight);
    }
    out = IsFinite(out) ? Max(out, Vec3f{}) : Vec3f{};
    output[i] = out;
    if (kept != output) kept[i] = out;
  }
};

}  // namespace cinevol
