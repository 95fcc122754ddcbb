// A client's pictures and files, through cinevol's own PNG coder.
#include "image_files.h"

#include <vector>

#include "encode/image_codecs.h"

namespace cinevol {

RgbImage DecodePngImage(const std::string& png) {
  ImageRgb8 image = DecodePng(std::vector<std::uint8_t>(png.begin(), png.end()));
  return {image.width, image.height, std::move(image.bytes)};
}

void WritePngFile(const std::filesystem::path& path, const RgbImage& image) {
  ImageRgb8 pixels;
  pixels.width = image.width;
  pixels.height = image.height;
  pixels.bytes = image.rgb;
  WriteFile(path, EncodePng(pixels));
}

void WriteBytesFile(const std::filesystem::path& path, const std::string& bytes) {
  WriteFile(path, std::vector<std::uint8_t>(bytes.begin(), bytes.end()));
}

}  // namespace cinevol
