// PSNR, SSIM, relative MSE and temporal error.
#include "image_metrics.h"

#include <algorithm>
#include <cmath>
#include <vector>
#include <stdexcept>

#include "core/parallel_for.h"
#include "core/sampling.h"
#include "core/tone_map.h"

namespace cinevol {

namespace {
void CheckSameSize(const ImageRgbF& a, const ImageRgbF& b) {
  if (a.width != b.width || a.height != b.height || a.pixels.size() != b.pixels.size()) {
    throw std::invalid_argument("images differ in size");
  }
}

float Displayed(float linear) { return LinearToSrgb(AcesFilm(std::isfinite(linear) ? linear : 0.0f)); }
}  // namespace

namespace {
// Mean over pixels and channels of the squared difference of display values.
double DisplayMse(const ImageRgbF& image, const ImageRgbF& reference) {
  CheckSameSize(image, reference);
  double mse = 0;
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const double d = Displayed(image.pixels[i][c]) - Displayed(reference.pixels[i][c]);
      mse += d * d;
    }
  }
  return mse / (3.0 * image.pixels.size());
}
}  // namespace

double DisplayPsnr(const ImageRgbF& image, const ImageRgbF& reference) {
  const double mse = DisplayMse(image, reference);
  return mse > 0 ? 10.0 * std::log10(1.0 / mse) : 100.0;
}

double DisplayRmsDifference(const ImageRgbF& a, const ImageRgbF& b) { return std::sqrt(DisplayMse(a, b)); }

double LevelBias(const ImageRgbF& image, const ImageRgbF& reference) {
  CheckSameSize(image, reference);
  double sum = 0, reference_sum = 0;
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    sum += IsFinite(image.pixels[i]) ? Luminance(image.pixels[i]) : 0.0f;
    reference_sum += Luminance(reference.pixels[i]);
  }
  return reference_sum > 0 ? sum / reference_sum - 1.0 : 0.0;
}

double RelativeMse(const ImageRgbF& image, const ImageRgbF& reference) {
  CheckSameSize(image, reference);
  double sum = 0;
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const double r = reference.pixels[i][c], d = image.pixels[i][c] - r;
      sum += d * d / (r * r + 1e-2);
    }
  }
  return sum / (3.0 * image.pixels.size());
}

namespace {

void CheckSameSize(const ImageRgb8& a, const ImageRgb8& b) {
  if (a.width != b.width || a.height != b.height || a.bytes.size() != b.bytes.size() || a.bytes.empty()) {
    throw std::invalid_argument("images differ in size");
  }
}

// Rec. 709 luma of pixel i, in [0, 1].
float Luma(const ImageRgb8& image, std::size_t i) {
  const std::uint8_t* p = &image.bytes[3 * i];
  return (0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2]) * (1.0f / 255.0f);
}

// Separable Gaussian blur (11 taps, sigma 1.5) with clamped edges.
std::vector<float> Blur(const std::vector<float>& in, int width, int height) {
  static const std::vector<float> kernel = [] {
    std::vector<float> k(11);
    float sum = 0;
    for (int i = 0; i < 11; ++i) sum += k[i] = std::exp(-float((i - 5) * (i - 5)) / (2.0f * 1.5f * 1.5f));
    for (float& v : k) v /= sum;
    return k;
  }();
  std::vector<float> tmp(in.size()), out(in.size());
  ParallelFor(height, [&](std::int64_t y) {
    for (int x = 0; x < width; ++x) {
      float s = 0;
      for (int k = -5; k <= 5; ++k) s += kernel[k + 5] * in[std::size_t(y) * width + std::clamp(x + k, 0, width - 1)];
      tmp[std::size_t(y) * width + x] = s;
    }
  }, 0, 16);
  ParallelFor(height, [&](std::int64_t y) {
    for (int x = 0; x < width; ++x) {
      float s = 0;
      for (int k = -5; k <= 5; ++k) {
        s += kernel[k + 5] * tmp[std::size_t(std::clamp(int(y) + k, 0, height - 1)) * width + x];
      }
      out[std::size_t(y) * width + x] = s;
    }
  }, 0, 16);
  return out;
}

}  // namespace

namespace {
// Mean squared difference in codes.
double CodeMse(const ImageRgb8& image, const ImageRgb8& reference) {
  CheckSameSize(image, reference);
  double mse = 0;
  for (std::size_t i = 0; i < image.bytes.size(); ++i) {
    const double d = double(image.bytes[i]) - reference.bytes[i];
    mse += d * d;
  }
  return mse / double(image.bytes.size());
}

double PsnrOfCodeMse(double mse) { return mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 100.0; }
}  // namespace

double Psnr(const ImageRgb8& image, const ImageRgb8& reference) { return PsnrOfCodeMse(CodeMse(image, reference)); }

double ReferenceNoise(const ImageRgbF& a, const ImageRgbF& b, int a_spp, int b_spp, float exposure) {
  if (a_spp < 1 || b_spp < 1) return 0.0;  // one sample: no second half to tell
  CheckSameSize(a, b);
  if (a.pixels.empty()) return 0.0;
  const float scale = std::exp2(exposure);
  double sum = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i) {
    std::uint8_t codes[3];
    float pa[3], pb[3];
    ToneMapPixel(a.pixels[i], scale, codes, pa);
    ToneMapPixel(b.pixels[i], scale, codes, pb);
    for (int c = 0; c < 3; ++c) sum += double(pa[c] - pb[c]) * (pa[c] - pb[c]);
  }
  const double n = double(a_spp) + b_spp;
  return sum / (3.0 * a.pixels.size()) * (double(a_spp) * b_spp / (n * n));
}

double CorrectedPsnr(const ImageRgb8& image, const ImageRgb8& reference, double reference_noise) {
  return PsnrOfCodeMse(CodeMse(image, reference) - reference_noise);
}

double Ssim(const ImageRgb8& image, const ImageRgb8& reference) {
  CheckSameSize(image, reference);
  const int w = image.width, h = image.height;
  const std::size_t n = std::size_t(w) * h;
  std::vector<float> a(n), b(n), aa(n), bb(n), ab(n);
  for (std::size_t i = 0; i < n; ++i) {
    a[i] = Luma(image, i);
    b[i] = Luma(reference, i);
    aa[i] = a[i] * a[i];
    bb[i] = b[i] * b[i];
    ab[i] = a[i] * b[i];
  }
  const std::vector<float> ma = Blur(a, w, h), mb = Blur(b, w, h), maa = Blur(aa, w, h), mbb = Blur(bb, w, h),
                           mab = Blur(ab, w, h);
  constexpr double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;
  double sum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double va = maa[i] - double(ma[i]) * ma[i], vb = mbb[i] - double(mb[i]) * mb[i];
    const double cov = mab[i] - double(ma[i]) * mb[i];
    sum += ((2 * ma[i] * mb[i] + c1) * (2 * cov + c2)) /
           ((double(ma[i]) * ma[i] + double(mb[i]) * mb[i] + c1) * (va + vb + c2));
  }
  return sum / double(n);
}

double TemporalError(const ImageRgb8& image, const ImageRgb8& previous_image, const ImageRgb8& reference,
                     const ImageRgb8& previous_reference) {
  CheckSameSize(image, reference);
  CheckSameSize(previous_image, previous_reference);
  CheckSameSize(image, previous_image);
  const std::size_t n = std::size_t(image.width) * image.height;
  double sum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    sum += std::abs((Luma(image, i) - Luma(previous_image, i)) - (Luma(reference, i) - Luma(previous_reference, i)));
  }
  return sum / double(n);
}

double RmsDifference(const ImageRgb8& a, const ImageRgb8& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.bytes.size(); ++i) sum += Sqr((float(a.bytes[i]) - float(b.bytes[i])) / 255.0f);
  return std::sqrt(sum / double(a.bytes.size()));
}

}  // namespace cinevol
