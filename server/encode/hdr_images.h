// Linear HDR images (radiance, environment maps): OpenEXR and PFM, 32-bit
// float RGB. Errors throw InputError naming the file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/image.h"

namespace cinevol {

std::vector<std::uint8_t> EncodeExr(const ImageRgbF& image);
void WriteExr(const std::filesystem::path& path, const ImageRgbF& image);
void WritePfm(const std::filesystem::path& path, const ImageRgbF& image);
// Messages call the file `shown` (default: its path). Images of more than
// 2^26 pixels are refused before any is read.
ImageRgbF ReadExr(const std::filesystem::path& path, const std::string& shown = {});
ImageRgbF ReadPfm(const std::filesystem::path& path);

}  // namespace cinevol
