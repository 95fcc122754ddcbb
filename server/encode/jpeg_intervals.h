// JPEG from YCbCr planes in restart intervals coded by encode/jpeg_blocks.h,
// on the CPU: the reference the GPU's encoder (pipeline/cuda_jpeg_encoder.cu)
// must match byte for byte, and what the tests check against libjpeg.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image.h"
#include "encode/jpeg_blocks.h"

namespace cinevol {

// Frame planes as the coder reads them.
jpeg::FramePlanes PlanesOf(const ImageYcc8& image);

// quality in [1, 100] (clamped); mcus_per_interval in [1, 65535].
std::vector<std::uint8_t> EncodeJpegInIntervals(const ImageYcc8& image, int quality, int mcus_per_interval);

}  // namespace cinevol
