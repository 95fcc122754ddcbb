// PSNR and relative MSE.
#include "core/image_metrics.h"

#include <cmath>
#include <stdexcept>

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

double DisplayPsnr(const ImageRgbF& image, const ImageRgbF& reference) {
  CheckSameSize(image, reference);
  double mse = 0;
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const double d = Displayed(image.pixels[i][c]) - Displayed(reference.pixels[i][c]);
      mse += d * d;
    }
  }
  mse /= 3.0 * image.pixels.size();
  return mse > 0 ? 10.0 * std::log10(1.0 / mse) : 100.0;
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

}  // namespace cinevol
