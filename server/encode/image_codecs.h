// Image files and streams: JPEG (libjpeg-turbo) and PNG (libpng) for 8-bit
// sRGB frames, JPEG also from YCbCr planes (linear HDR: hdr_images.h). What
// a client needs to show frames, nothing more. Errors throw InputError
// naming the file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "core/image.h"

namespace cinevol {

// quality in [1, 100]; chroma subsampling as ChromaSubsampling (core/image.h).
std::vector<std::uint8_t> EncodeJpeg(const ImageRgb8& image, int quality,
                                     ChromaSubsampling chroma = ChromaSubsampling::k420);
// From planes already converted and downsampled (the display's frames):
// libjpeg's raw-data path, which skips its colour conversion and downsampling.
// With bands > 1, horizontal bands of whole MCU rows encode on as many
// threads of the shared pool (those it has free) and join as restart
// intervals: the same pixels decode, sooner.
std::vector<std::uint8_t> EncodeJpeg(const ImageYcc8& image, int quality, int bands = 1);
std::vector<std::uint8_t> EncodePng(const ImageRgb8& image);
// Decoders allocate at most 8192 x 8192 pixels (the largest viewport).
ImageRgb8 DecodeJpeg(const std::vector<std::uint8_t>& bytes);
ImageRgb8 DecodePng(const std::vector<std::uint8_t>& bytes);
ImageRgb8 ReadPng(const std::filesystem::path& path);

void WriteFile(const std::filesystem::path& path, const std::vector<std::uint8_t>& bytes);

}  // namespace cinevol
