// Image error metrics for tests and benchmarks. PSNR is taken on what a
// viewer sees (tone-mapped sRGB in [0, 1], exposure 0), so HDR outliers
// count as much as they show; relative MSE is taken on linear radiance.
#pragma once

#include "core/image.h"

namespace cinevol {

// PSNR in dB of `image` against `reference` after tone mapping.
double DisplayPsnr(const ImageRgbF& image, const ImageRgbF& reference);

// The RMS difference of two HDR images once tone-mapped to display values in
// [0, 1] (as DisplayPsnr, before 8-bit rounding): flicker without the
// rounding's own, which flips codes on changes of a fraction of a code.
double DisplayRmsDifference(const ImageRgbF& a, const ImageRgbF& b);

// The mean luminance of `image` relative to the reference's, minus 1: a
// denoiser's bias, which PSNR mixes with its noise.
double LevelBias(const ImageRgbF& image, const ImageRgbF& reference);

// Mean over pixels and channels of (x - r)^2 / (r^2 + 1e-2).
double RelativeMse(const ImageRgbF& image, const ImageRgbF& reference);

// On displayed 8-bit sRGB images (after tone mapping, and after JPEG where
// that applies):
// PSNR in dB over the three channels (peak 255); 100 for identical images.
double Psnr(const ImageRgb8& image, const ImageRgb8& reference);
// The variance a reference's own noise adds to an image's squared error
// against it, in 8-bit codes squared (as Psnr's). The reference is the mean,
// by samples, of two halves rendered with independent seeds, `a` of `a_spp`
// samples and `b` of `b_spp`; the halves' display values differ by their
// noise alone, and their squared difference, scaled by a_spp b_spp /
// (a_spp + b_spp)^2, is what the whole reference's noise is expected to be
// (to first order in the display curve). 0 where a half has no samples.
double ReferenceNoise(const ImageRgbF& a, const ImageRgbF& b, int a_spp, int b_spp, float exposure);
// PSNR against the converged image the reference estimates: the squared
// error against `reference` less `reference_noise` (ReferenceNoise), an
// unbiased estimate where the image's noise is independent of the
// reference's. A good denoiser's error is near the noise of a reference of a
// few hundred samples, which then hides most of the difference between two
// of them (docs/tradeoff.md). 100 where nothing is left.
double CorrectedPsnr(const ImageRgb8& image, const ImageRgb8& reference, double reference_noise);
// SSIM (Wang et al. 2004: 11x11 Gaussian window, sigma 1.5, K1 0.01, K2 0.03)
// of the Rec. 709 luma, averaged over the image.
double Ssim(const ImageRgb8& image, const ImageRgb8& reference);
// Temporal error: the mean over pixels of |(O_t - O_t-1) - (R_t - R_t-1)| in
// luma, in [0, 1] units: flicker and lag that the reference does not have.
double TemporalError(const ImageRgb8& image, const ImageRgb8& previous_image, const ImageRgb8& reference,
                     const ImageRgb8& previous_reference);
// The RMS difference of two images over all channels, in [0, 1] units: on
// consecutive frames of a still view, the flicker a viewer sees.
double RmsDifference(const ImageRgb8& a, const ImageRgb8& b);

}  // namespace cinevol
