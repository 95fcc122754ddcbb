// Image error metrics for tests and benchmarks. PSNR is taken on what a
// viewer sees (tone-mapped sRGB in [0, 1], exposure 0), so HDR outliers
// count as much as they show; relative MSE is taken on linear radiance.
#pragma once

#include "core/image.h"

namespace cinevol {

// PSNR in dB of `image` against `reference` after tone mapping.
double DisplayPsnr(const ImageRgbF& image, const ImageRgbF& reference);

// Mean over pixels and channels of (x - r)^2 / (r^2 + 1e-2).
double RelativeMse(const ImageRgbF& image, const ImageRgbF& reference);

}  // namespace cinevol
