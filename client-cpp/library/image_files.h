// Pictures and files a client reads and writes beside the stream: a slice's
// PNG into pixels, a window's pixels into a PNG file, a still's bytes into a
// file. (A frame's own image: DecodeFrame in client.h.)
#pragma once

#include <filesystem>
#include <string>

#include "client.h"

namespace cinevol {

// Throws std::runtime_error when `png` is not a PNG.
RgbImage DecodePngImage(const std::string& png);
// Throws std::runtime_error when the file cannot be written.
void WritePngFile(const std::filesystem::path& path, const RgbImage& image);
void WriteBytesFile(const std::filesystem::path& path, const std::string& bytes);

}  // namespace cinevol
