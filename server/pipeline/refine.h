// Idle refinement: while the view holds still, the displayed image combines,
// per pixel, the denoiser's output d and the running mean m of the frames,
// by their estimated errors. The mean's error is its variance V (the spread
// of the frame means over their count). The denoiser's, B, is the part of
// the squared difference D = (d - m)^2 that the mean's noise does not
// explain: B = max(0, D - V). This takes d and m as independent; d is made
// of the same frames, so where the denoiser leans on a pixel's own recent
// values B comes out low and the mean takes over later than it could.
// Counting the covariance as V instead (B = D + V, exact for a plain average
// of recent frames) kept the mean at least half in every pixel and cost 7 dB
// at 720p the moment blending began (docs/tradeoff.md, "Still frames"). Both
// are averaged over a small window (single pixels are too noisy to steer
// by), and a pixel whose own spread is larger than its window's (a firefly)
// keeps its own:
//
//   shown = d + w (m - d),  w = B / (B + V),
//
// the weight that minimises the expected squared error, w^2 V + (1 - w)^2 B =
// B V / (B + V). The mean takes over wherever it is the better estimate, and
// everywhere as V falls (measured: never below the mean once blending
// starts, tests/pipeline/refine_test.cpp). The same
// expected error, over the image, is what refinement stops at
// (FrameSettings::error_target). Runs on the backend that rendered the frame.
#pragma once

#include <cmath>
#include <memory>

#include "core/sampling.h"
#include "core/vec.h"

namespace cinevol {

// Half-width of the window the error estimates are averaged over (7x7).
inline constexpr int kErrorWindowRadius = 3;
// Frames before the variance is estimated: fewer give too noisy a spread.
inline constexpr int kMinFramesForError = 16;
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

// Before the denoiser: the frame's squares join the accumulation's, and the
// variance of the mean (mean over channels) is written out.
struct VariancePass {
  const Vec3f* frame;            // this frame's radiance: the mean of its samples
  const Vec3f* accumulated_sum;  // sum of frame means, this one included
  Vec3f* squares;                // sum of squared frame means (this pass adds this frame's)
  float* variance;               // of the mean: the sample variance of the frames / frames, relative
  int width, frames;
  float dark;                    // RelativeScale's floor

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const Vec3f r = frame[i];
    const Vec3f q = (frames == 1 ? Vec3f{} : squares[i]) + r * r;
    squares[i] = q;
    const float n = float(frames);
    const Vec3f m = accumulated_sum[i] * (1.0f / n);
    if (frames < 2) {
      variance[i] = 0.0f;
      return;
    }
    const Vec3f spread = q - m * m * n;  // sum of squared deviations
    const float sum = fmaxf(spread.x, 0.0f) + fmaxf(spread.y, 0.0f) + fmaxf(spread.z, 0.0f);
    variance[i] = sum / (3.0f * (n - 1.0f) * n) * RelativeScale(m, dark);
  }
};

// After the denoiser: the squared difference of d and m, mean over
// channels, relative.
struct DifferencePass {
  const Vec3f* denoised;
  const Vec3f* accumulated_sum;
  float inv_frames;
  float* difference;
  int width;
  float dark;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    const Vec3f m = accumulated_sum[i] * inv_frames;
    const Vec3f e = denoised[i] - m;
    difference[i] = Dot(e, e) * (1.0f / 3.0f) * RelativeScale(m, dark);
  }
};

// The blend, and each pixel's expected squared relative error.
struct BlendPass {
  const Vec3f* denoised;
  const Vec3f* accumulated_sum;
  float inv_frames;
  const float* variance;
  const float* difference;
  Vec3f* shown;
  float* error;
  int width, height, frames;

  CINEVOL_HD void operator()(int x, int y) const {
    float v = 0.0f, d = 0.0f;
    int count = 0;
    for (int wy = MaxInt(y - kErrorWindowRadius, 0); wy <= MinInt(y + kErrorWindowRadius, height - 1); ++wy) {
      for (int wx = MaxInt(x - kErrorWindowRadius, 0); wx <= MinInt(x + kErrorWindowRadius, width - 1); ++wx) {
        v += variance[wy * width + wx];
        d += difference[wy * width + wx];
        ++count;
      }
    }
    v /= float(count);
    d /= float(count);
    const int i = y * width + x;
    // The spread of n frames is itself uncertain (relative standard error
    // about sqrt(2 / (n - 1))): the mean takes over only on the evidence,
    // with the spread counted at its upper error bar.
    const float upper = 1.0f + sqrtf(2.0f / float(MaxInt(frames - 1, 1)));
    const float bias = fmaxf(d - upper * v, 0.0f);
    // A firefly's pixel has a far larger spread than its window: its own.
    const float spread = upper * fmaxf(variance[i], v);
    // No spread and no difference: the mean is exact (empty space, or one value).
    const float w = bias + spread > 0.0f ? bias / (bias + spread) : 1.0f;
    shown[i] = denoised[i] + (accumulated_sum[i] * inv_frames - denoised[i]) * w;
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
  const Vec3f* frame = nullptr;            // backend memory: this frame's radiance
  const Vec3f* accumulated_sum = nullptr;  // backend memory: sum of the frames, this one included
  const Vec3f* denoised = nullptr;         // backend memory
  int frames = 0;                          // in accumulated_sum; 1 restarts the squares
  float exposure = 0;                      // the display's, in stops: errors are weighed as shown
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
  // Every full-size frame: takes its radiance into the squares, and from
  // kMinFramesForError frames on blends (before, too few frames have too
  // noisy a spread to go by, and the denoiser's output is shown as it is).
  virtual RefinedImage Refine(const RefineInputs& in) = 0;
};

template <class B>
class RefinerOn final : public Refiner {
 public:
  RefinedImage Refine(const RefineInputs& in) override {
    const std::size_t n = std::size_t(in.width) * in.height;
    const float dark = kDarkGrey / exp2f(in.exposure);
    squares_.Resize(n);
    variance_.Resize(n);
    B::ForEachPixel(in.width, in.height,
                    VariancePass{in.frame, in.accumulated_sum, squares_.data(), variance_.data(), in.width,
                                 in.frames, dark});
    if (in.frames < kMinFramesForError) return {in.denoised, -1.0f};

    difference_.Resize(n);
    shown_.Resize(n);
    error_.Resize(n);
    row_sums_.Resize(std::size_t(in.height));
    const float inv_frames = 1.0f / float(in.frames);
    B::ForEachPixel(in.width, in.height,
                    DifferencePass{in.denoised, in.accumulated_sum, inv_frames, difference_.data(), in.width, dark});
    B::ForEachPixel(in.width, in.height,
                    BlendPass{in.denoised, in.accumulated_sum, inv_frames, variance_.data(), difference_.data(),
                              shown_.data(), error_.data(), in.width, in.height, in.frames});
    B::ForEachPixel(1, in.height, RowSumPass{error_.data(), row_sums_.data(), in.width});
    double error = 0;
    for (const float row : row_sums_.Download()) error += row;
    return {shown_.data(), float(std::sqrt(error / double(n)))};
  }

 private:
  typename B::template Buffer<Vec3f> squares_, shown_;
  typename B::template Buffer<float> variance_, difference_, error_, row_sums_;
};

std::unique_ptr<Refiner> MakeCpuRefiner();
#if CINEVOL_WITH_CUDA
std::unique_ptr<Refiner> MakeCudaRefiner();
#endif

}  // namespace cinevol
