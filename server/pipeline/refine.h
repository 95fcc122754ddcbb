// Idle refinement: while the view holds still, the displayed image combines,
// per pixel, the denoiser's output d and an estimate a made from the frames
// accumulated so far, by their estimated errors.
//
// The accumulation's estimate. The mean m of the samples (each frame weighs
// by its samples: VariancePass) has error V, its variance (the spread of the
// frame means over their count). A variance-
// guided a-trous filter (SVGF's, steered by V) smooths it where neighbours
// agree within their noise. Its variance V_f cannot be propagated through
// the filter's levels (they correlate neighbours, and the weights depend on
// the noise: propagating as if independent put V_f 20 times too low), so
// the frames are kept in two halves, odd and even, each filtered alone: f is
// their average, and V_f = (f_odd - f_even)^2 / 4, averaged over a window,
// measures its variance directly (the two-buffer estimate of NFOR and
// Rousselle et al.). f's bias b^2 is the part of the cross-half change,
// (f_odd - m_even)^2, that the halves' independent noises do not explain.
// m and f then combine as two correlated estimators of errors V and
// e_f = b^2 + V_f (EstimatePass): a = f + u (m - f), with the u of least
// expected squared error E.
//
// The blend. The denoiser's error B follows from D = (d - a)^2 = B + E - 2C,
// C their covariance: d is made of the same frames as a, and C = E is exact
// where d is a plain average of them (measured 0.9 E on the MR head), so
// B = D + E. (With the unfiltered mean, whose error is far larger, counting
// C this way kept the mean at least half in every pixel and cost 7 dB at
// 720p; taking d and m as independent, B = D - V, was right then: the
// history is in docs/tradeoff.md, "Still frames".) Estimates are averaged
// over a small window (single pixels are too noisy to steer by), and a
// pixel whose own error is larger than its window's (a firefly) keeps its own:
//
//   shown = d + w (a - d),  w = B / (B + E),
//
// the weight that minimises the expected squared error, w^2 E + (1 - w)^2 B =
// B E / (B + E). The accumulation takes over wherever it is the better
// estimate, and everywhere as its error falls (measured: within 0.3 dB of
// the mean once blending starts, ahead of it at the end,
// tests/pipeline/refine_test.cpp). The same
// expected error, over the image, is what refinement stops at
// (FrameSettings::error_target). Runs on the backend that rendered the frame.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <utility>

#include "core/image.h"
#include "core/sampling.h"
#include "core/vec.h"
#include "denoise/baselines.h"
#include "denoise/cpu_passes.h"
#include "device/frame_scratch.h"

namespace cinevol {

// Half-width of the window the error estimates are averaged over (7x7).
inline constexpr int kErrorWindowRadius = 3;
// Frames before the variance is estimated: fewer give too noisy a spread.
inline constexpr int kMinFramesForError = 16;
// The frames a still view's denoiser output remembers: wRLS's accumulates
// over at most 32 (WrlsSettings::stabilize_still_frames), an average that
// forgets older ones. B = D + E takes d as sharing every frame of a; measured
// (docs/tradeoff.md, "Past the denoiser's memory"), that reads B low once the
// accumulation outgrows this memory, so BlendPass adds one E to B for each
// further memory's worth of frames: a floor near the variance of a mean of
// this many frames, since E falls as 1 / frames.
inline constexpr float kDenoiserMemoryFrames = 32.0f;
// Linear radiance shown as 2% grey at exposure 0: RelativeScale's floor.
inline constexpr float kDarkGrey = 0.02f;

// Errors are weighed relative to the pixel's brightness, as a viewer sees
// them (sRGB spends its codes on ratios): 1 / (luminance + dark)^2, where
// `dark` is a floor at the display's 2% grey, so that black pixels do not
// weigh without bound.
CINEVOL_HD float RelativeScale(Vec3f radiance, float dark) {
  const float l = fmaxf(Luminance(radiance), 0.0f) + dark;
  return 1.0f / (l * l);
}

// The relative RMS error of `image` against `reference`, weighed as the
// refiner's estimate is: what benches and tests hold the estimate against.
inline double RelativeRmsError(const ImageRgbF& image, const ImageRgbF& reference, float dark) {
  double sum = 0;
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    const Vec3f e = image.pixels[i] - reference.pixels[i];
    sum += Dot(e, e) / 3.0f * RelativeScale(reference.pixels[i], dark);
  }
  return std::sqrt(sum / double(image.pixels.size()));
}

// Before the denoiser: the frame's squares join the accumulation's, an odd
// frame joins the odd half, and the variance of the mean (mean over
// channels) is written out. Frames may differ in samples (a CPU session's
// still frames take more as they go, frame_cost.h): each weighs by its
// samples s, as in the accumulation (the sum of every sample), so the mean m
// is the plain mean of the samples. With the frame means x_i, the weighted
// squared deviations sum_i s_i (x_i - m)^2 estimate (n - 1) times a sample's
// variance, and m's variance is that over the samples S; equal frames give
// the unweighted sample variance of the frames over n.
struct VariancePass {
  const Vec3f* frame;            // this frame's radiance: the mean of its samples
  const Vec3f* accumulated_sum;  // sum of every sample so far, this frame's included
  Vec3f* squares;                // sum of s_i x_i^2 (this pass adds this frame's)
  Vec3f* odd_sum;                // sum of the samples of frames 1, 3, 5...
  float* variance;               // of the mean, relative
  int width, frames;             // frames >= 2: the first frame is read back from the sum at the second
  int spp;                       // this frame's samples per pixel
  float samples;                 // S: samples per pixel in accumulated_sum
  float dark;                    // RelativeScale's floor

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const Vec3f r = frame[i];
    const float s = float(spp);
    const Vec3f sum = accumulated_sum[i];
    Vec3f q = r * r * s;
    if (frames == 2) {
      // Frame 1 is the sum less this frame's samples (clamped: radiance is
      // never negative, the difference may round below 0).
      const float s1 = samples - s;
      const Vec3f r1 = Max(sum - r * s, Vec3f{}) * (1.0f / s1);
      q += r1 * r1 * s1;
      odd_sum[i] = r1 * s1;
    } else {
      q += squares[i];
      if (frames % 2 == 1) odd_sum[i] += r * s;
    }
    squares[i] = q;
    const Vec3f m = sum * (1.0f / samples);
    const Vec3f spread = q - m * m * samples;  // sum of weighted squared deviations
    const float total = fmaxf(spread.x, 0.0f) + fmaxf(spread.y, 0.0f) + fmaxf(spread.z, 0.0f);
    variance[i] = total / (3.0f * (float(frames) - 1.0f) * samples) * RelativeScale(m, dark);
  }
};

// One level of the accumulation's a-trous filter (the denoisers' taps,
// AtrousTaps in denoise/baselines.h): a neighbour counts unless it differs
// from the centre by more than their noise explains (in any channel,
// relative, against kMeanFilterSigma standard deviations of the
// difference). The variance in w steers the next level, propagated as if
// pixels were independent (it only steers: the estimate's error is measured
// from the two halves). As samples grow the noise, and with it what the
// filter averages, shrinks: f tends to m.
inline constexpr float kMeanFilterSigma = 2.0f;
inline constexpr int kMeanFilterLevels = 3;  // steps 1, 2, 4: a 17x17 footprint

struct MeanFilterPass {
  const Vec4f* in;  // rgb: a half's (filtered) mean; w: its relative variance
  Vec4f* out;
  int width, height, step;
  float dark;       // RelativeScale's floor

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const Vec4f c = in[i];
    const float inv_l = 1.0f / (fmaxf(Luminance(Xyz(c)), 0.0f) + dark);
    out[i] = AtrousTaps(in, x, y, width, height, step, [&](int, Vec4f q, float log2_kernel) {
      const float difference = fmaxf(fabsf(q.x - c.x), fmaxf(fabsf(q.y - c.y), fabsf(q.z - c.z))) * inv_l;
      const float noise = kMeanFilterSigma * sqrtf(c.w + q.w) + 1e-7f;
      return FastExp2(log2_kernel - difference / noise * kLog2e);  // kernel * e^(-difference / noise)
    });
  }
};

// One MeanFilterPass level over the whole frame, as vectorised rows of the
// same weights (cpu_refine.cpp); RunAtrousLevel picks it on the CPU.
void CpuAtrousLevel(const MeanFilterPass& pass);

// One half's mean (odd frames, or even ones) and its variance, about twice
// the whole mean's (the halves' samples differ by a frame's at most), packed
// for MeanFilterPass.
struct HalfMeanPass {
  const Vec3f* accumulated_sum;
  const Vec3f* odd_sum;
  const float* variance;
  Vec4f* out;
  int width;
  float half_samples;  // the half's samples per pixel
  bool odd;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const Vec3f sum = odd ? odd_sum[i] : accumulated_sum[i] - odd_sum[i];
    out[i] = ToVec4(sum * (1.0f / half_samples), 2.0f * variance[i]);
  }
};

// Per pixel, for EstimatePass's window, all relative: what the filter
// changed, (f - m)^2, f being the filtered halves' average; each half's
// filtered mean against the other half's mean, (f_odd - m_even)^2 and
// (f_even - m_odd)^2 averaged, whose noises are independent; and the
// two-half measure of f's variance, (f_odd - f_even)^2 / 4.
struct FilteredPass {
  const Vec3f* accumulated_sum;
  const Vec3f* odd_sum;
  float samples, odd_samples;  // per pixel: in accumulated_sum, in odd_sum
  const Vec4f* odd;   // filtered halves
  const Vec4f* even;
  float* change;
  float* cross_change;
  float* filter_variance;
  int width;
  float dark;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const Vec3f m = accumulated_sum[i] * (1.0f / samples);
    const Vec3f m_odd = odd_sum[i] * (1.0f / odd_samples);
    const Vec3f m_even = (accumulated_sum[i] - odd_sum[i]) * (1.0f / (samples - odd_samples));
    const Vec3f f_odd = Xyz(odd[i]), f_even = Xyz(even[i]);
    const Vec3f f = (f_odd + f_even) * 0.5f;
    const Vec3f e = f - m, h = (f_odd - f_even) * 0.5f, c1 = f_odd - m_even, c2 = f_even - m_odd;
    const float scale = (1.0f / 3.0f) * RelativeScale(m, dark);
    change[i] = Dot(e, e) * scale;
    cross_change[i] = 0.5f * (Dot(c1, c1) + Dot(c2, c2)) * scale;
    filter_variance[i] = Dot(h, h) * scale;
  }
};

// Means of N per-pixel quantities over the error window around (x, y).
template <int N>
CINEVOL_HD void WindowMean(const float* const (&in)[N], float (&out)[N], int x, int y, int width, int height) {
  for (int k = 0; k < N; ++k) out[k] = 0.0f;
  int count = 0;
  for (int wy = MaxInt(y - kErrorWindowRadius, 0); wy <= MinInt(y + kErrorWindowRadius, height - 1); ++wy) {
    for (int wx = MaxInt(x - kErrorWindowRadius, 0); wx <= MinInt(x + kErrorWindowRadius, width - 1); ++wx) {
      for (int k = 0; k < N; ++k) out[k] += in[k][wy * width + wx];
      ++count;
    }
  }
  for (int k = 0; k < N; ++k) out[k] /= float(count);
}

// The accumulation's estimate a of m and f, and its error E. A half's mean
// has variance 2V and a half's filtered mean 2V_f, so f's squared bias is
// what the cross-half change leaves of them; f's error is e_f = b^2 + V_f.
// f and m are correlated (f keeps part of m's own pixel): their covariance
// C is what (f - m)^2 falls short of e_f + V by. The combination of two
// correlated estimators with the least expected squared error:
//
//   u = (e_f - C) / (e_f + V - 2C),  E = (e_f V - C^2) / (e_f + V - 2C).
struct EstimatePass {
  const Vec3f* accumulated_sum;
  float inv_samples;
  const float* variance;  // V
  const Vec4f* odd;       // filtered halves
  const Vec4f* even;
  const float* change;    // FilteredPass
  const float* cross_change;
  const float* filter_variance;
  Vec3f* estimate;
  float* estimate_error;
  int width, height;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    float w[4];
    WindowMean<4>({change, cross_change, variance, filter_variance}, w, x, y, width, height);
    const float bias = fmaxf(w[1] - 2.0f * (w[2] + w[3]), 0.0f);
    const float e_f = bias + w[3];
    // A firefly in the mean has a far larger variance than its window: its own.
    const float v = fmaxf(variance[i], w[2]);
    const float c = fminf(fmaxf(0.5f * (e_f + w[2] - w[0]), 0.0f), fminf(e_f, v));
    const float spread = e_f + v - 2.0f * c;
    const float u = spread > 0.0f ? (e_f - c) / spread : 0.0f;
    const Vec3f f = (Xyz(odd[i]) + Xyz(even[i])) * 0.5f;
    estimate[i] = f + (accumulated_sum[i] * inv_samples - f) * u;
    estimate_error[i] = spread > 0.0f ? fmaxf(e_f * v - c * c, 0.0f) / spread : 0.0f;
  }
};

// The squared difference of the denoiser's output and the accumulation's
// estimate, mean over channels, relative.
struct DifferencePass {
  const Vec3f* denoised;
  const Vec3f* estimate;
  float* difference;
  int width;
  float dark;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const Vec3f e = denoised[i] - estimate[i];
    difference[i] = Dot(e, e) * (1.0f / 3.0f) * RelativeScale(estimate[i], dark);
  }
};

// The blend of d and a, and each pixel's expected squared relative error.
struct BlendPass {
  const Vec3f* denoised;
  const Vec3f* estimate;
  const float* estimate_error;  // E
  const float* difference;      // (d - a)^2
  Vec3f* shown;
  float* error;
  int width, height, frames;

  CINEVOL_HD void operator()(int x, int y) const {
    float m[2];
    WindowMean<2>({estimate_error, difference}, m, x, y, width, height);
    const int i = y * width + x;
    // The spread of n frames is itself uncertain (relative standard error
    // about sqrt(2 / (n - 1))): the accumulation takes over only on the
    // evidence, with its error counted at its upper error bar.
    const float upper = 1.0f + sqrtf(2.0f / float(MaxInt(frames - 1, 1)));
    // D = B + E - 2C, C the covariance of d and a. d averages the same
    // frames as a: C = E (exact where d is a plain average of them; on the
    // MR head the measured C was 0.9 E), so B = D + E, here D + (2 - upper) E.
    // Past the denoiser's memory (kDenoiserMemoryFrames) one more E for each further memory's worth of frames.
    const float forgotten = fmaxf(float(frames) - kDenoiserMemoryFrames, 0.0f) / kDenoiserMemoryFrames;
    const float bias = fmaxf(m[1] + (2.0f - upper + forgotten) * m[0], 0.0f);
    const float spread = upper * fmaxf(estimate_error[i], m[0]);
    // No spread and no difference: the accumulation is exact (empty space, or one value).
    const float w = bias + spread > 0.0f ? bias / (bias + spread) : 1.0f;
    shown[i] = denoised[i] + (estimate[i] - denoised[i]) * w;
    error[i] = w * w * spread + (1.0f - w) * (1.0f - w) * bias;
  }
};

// Sums of each row's errors (one thread a row): a reduction both backends
// can run; the host adds the rows.
struct RowSumPass {
  const float* error;
  float* row_sums;
  int width;

  CINEVOL_HD void operator()(int, int y) const {
    float sum = 0.0f;
    for (int x = 0; x < width; ++x) sum += error[y * width + x];
    row_sums[y] = sum;
  }
};

// One full-size frame, after the denoiser.
struct RefineInputs {
  int width = 0, height = 0;
  const Vec3f* frame = nullptr;            // backend memory: this frame's radiance (its samples' mean)
  const Vec3f* accumulated_sum = nullptr;  // backend memory: sum of every sample, this frame's included
  const Vec3f* denoised = nullptr;         // backend memory
  int frames = 0;                          // in accumulated_sum; 1 restarts the squares
  float exposure = 0;                      // the display's, in stops: errors are weighed as shown
  int spp = 0;                             // this frame's samples per pixel
  std::int64_t samples = 0;                // per pixel in accumulated_sum, this frame's included
};

// What a refined frame shows.
struct RefinedImage {
  const Vec3f* radiance = nullptr;  // backend memory, valid until the next Refine
  // Expected relative error of the image: the root of the mean over pixels
  // of their expected squared relative errors. Negative until
  // kMinFramesForError frames have accumulated.
  float estimated_error = -1.0f;
};

class Refiner {
 public:
  virtual ~Refiner() = default;
  // Every full-size frame: takes its radiance into the squares and the odd
  // or even half (the first frame's at the second, from the sum), and from
  // kMinFramesForError frames on blends (before, too few frames have too
  // noisy a spread to go by, and the denoiser's output is shown as it is).
  virtual RefinedImage Refine(const RefineInputs& in) = 0;
  // The last blended image on the host (benches measure its error); empty
  // before kMinFramesForError frames.
  virtual ImageRgbF Output() const = 0;
};

template <class B>
class RefinerOn final : public Refiner {
 public:
  RefinedImage Refine(const RefineInputs& in) override {
    const std::size_t n = std::size_t(in.width) * in.height;
    const int w = in.width, h = in.height;
    const float dark = kDarkGrey / exp2f(in.exposure);
    squares_.Resize(n);
    odd_sum_.Resize(n);
    // Every frame before this one took a sample at least: the second frame
    // divides by the first's.
    if (in.frames < 1 || in.spp < 1 || in.samples < std::int64_t(in.spp) + (in.frames - 1))
      throw std::invalid_argument("Refiner::Refine: a frame's samples and the accumulation's");
    width_ = height_ = 0;
    // A first frame adds nothing to the spread: the next frame reads it back
    // from the sum (every moving frame is a first frame, and skips the pass).
    if (in.frames == 1) return {in.denoised, -1.0f};
    if (in.frames == 2) odd_samples_ = in.samples - in.spp;
    if (in.frames % 2 == 1) odd_samples_ += in.spp;
    const float samples = float(in.samples);
    const FramePlanes f(n);
    B::ForEachPixel(w, h, VariancePass{in.frame, in.accumulated_sum, squares_.data(), odd_sum_.data(), f.variance, w,
                                       in.frames, in.spp, samples, dark});
    if (in.frames < kMinFramesForError) return {in.denoised, -1.0f};

    const float inv_samples = 1.0f / samples;
    shown_.Resize(n);
    const float odd_samples = float(odd_samples_);
    const Vec4f* odd = FilterHalf(in, true, odd_samples, dark, f);
    const Vec4f* even = FilterHalf(in, false, samples - odd_samples, dark, f);
    B::ForEachPixel(w, h, FilteredPass{in.accumulated_sum, odd_sum_.data(), samples, odd_samples, odd, even, f.change,
                                       f.cross_change, f.filter_variance, w, dark});
    B::ForEachPixel(w, h, EstimatePass{in.accumulated_sum, inv_samples, f.variance, odd, even, f.change,
                                       f.cross_change, f.filter_variance, f.estimate, f.estimate_error, w, h});
    float* difference = f.change;  // the change is spent
    B::ForEachPixel(w, h, DifferencePass{in.denoised, f.estimate, difference, w, dark});
    B::ForEachPixel(w, h, BlendPass{in.denoised, f.estimate, f.estimate_error, difference, shown_.data(), f.error, w,
                                    h, in.frames});
    width_ = w;
    height_ = h;
    row_sums_.Resize(std::size_t(h));
    B::ForEachPixel(1, h, RowSumPass{f.error, row_sums_.data(), w});
    double error = 0;
    for (const float row : row_sums_.Download()) error += row;
    return {shown_.data(), float(std::sqrt(error / double(n)))};
  }

  ImageRgbF Output() const override {
    if (width_ == 0) return {};
    return {width_, height_, shown_.Download()};
  }

 private:
  // What a frame's blend needs only while it is made, in frame scratch
  // (device/frame_scratch.h): 84 bytes a pixel, which a resting session
  // otherwise held.
  struct FramePlanes {
    float* variance;  // VariancePass's, of the mean, relative
    float *change, *cross_change, *filter_variance, *estimate_error, *error;
    Vec4f* halves[3];  // the odd half's mean ends in [1], the even's in [2]; [0] is their ping-pong
    Vec3f* estimate;

    explicit FramePlanes(std::size_t n) : estimate(B::template FrameScratch<Vec3f>(Scratch::kRefineEstimate, n)) {
      float* plane = B::template FrameScratch<float>(Scratch::kRefinePlanes, 6 * n);
      for (float** p : {&variance, &change, &cross_change, &filter_variance, &estimate_error, &error}) {
        *p = plane;
        plane += n;
      }
      Vec4f* half = B::template FrameScratch<Vec4f>(Scratch::kRefineHalves, 3 * n);
      for (Vec4f*& h : halves) {
        h = half;
        half += n;
      }
    }
  };

  // One half's mean through kMeanFilterLevels levels, in f.halves.
  const Vec4f* FilterHalf(const RefineInputs& in, bool odd, float half_samples, float dark, const FramePlanes& f) {
    const int w = in.width, h = in.height;
    Vec4f* result = f.halves[odd ? 1 : 2];
    // Ping-pong between scratch and result, ending in result.
    Vec4f* from = kMeanFilterLevels % 2 == 0 ? result : f.halves[0];
    Vec4f* to = kMeanFilterLevels % 2 == 0 ? f.halves[0] : result;
    B::ForEachPixel(w, h, HalfMeanPass{in.accumulated_sum, odd_sum_.data(), f.variance, from, w, half_samples, odd});
    for (int level = 0; level < kMeanFilterLevels; ++level) {
      RunAtrousLevel<B>(MeanFilterPass{from, to, w, h, 1 << level, dark});
      std::swap(from, to);
    }
    return from;
  }

  int width_ = 0, height_ = 0;  // of the last blend; 0 where none
  std::int64_t odd_samples_ = 0;  // per pixel in odd_sum_
  // 36 bytes a pixel, and the frame's planes (FramePlanes).
  typename B::template Buffer<Vec3f> squares_, odd_sum_, shown_;
  typename B::template Buffer<float> row_sums_;
};

std::unique_ptr<Refiner> MakeCpuRefiner();
#if CINEVOL_WITH_CUDA
std::unique_ptr<Refiner> MakeCudaRefiner();
#endif

}  // namespace cinevol
