// Linear HDR images: OpenEXR, and a small PFM reader/writer.
#include "encode/hdr_images.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>

#include <cstdio>
#include <cstring>
#include <fstream>

#include <fmt/format.h>

#include "core/error.h"
#include "encode/image_codecs.h"  // WriteFile

namespace fs = std::filesystem;

namespace cinevol {

namespace {

// OpenEXR writes through a stream; this one grows a byte vector.
class MemoryStream final : public Imf::OStream {
 public:
  MemoryStream() : Imf::OStream("memory") {}
  void write(const char c[], int n) override {
    if (position_ + n > bytes_.size()) bytes_.resize(position_ + n);
    std::memcpy(bytes_.data() + position_, c, std::size_t(n));
    position_ += std::size_t(n);
  }
  uint64_t tellp() override { return position_; }
  void seekp(uint64_t position) override { position_ = position; }
  std::vector<std::uint8_t> Take() { return std::move(bytes_); }

 private:
  std::vector<std::uint8_t> bytes_;
  std::size_t position_ = 0;
};

}  // namespace

std::vector<std::uint8_t> EncodeExr(const ImageRgbF& image) {
  if (image.width <= 0 || image.height <= 0 || image.pixels.size() != std::size_t(image.width) * image.height) {
    throw std::invalid_argument("image buffer does not match its size");
  }
  Imf::Header header(image.width, image.height);
  Imf::FrameBuffer frame;
  const char* names[3] = {"R", "G", "B"};
  char* base = reinterpret_cast<char*>(const_cast<Vec3f*>(image.pixels.data()));
  for (int c = 0; c < 3; ++c) {
    header.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
    frame.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), sizeof(Vec3f),
                                      sizeof(Vec3f) * image.width));
  }
  MemoryStream stream;
  {
    Imf::OutputFile file(stream, header);  // finishes the file when it goes out of scope
    file.setFrameBuffer(frame);
    file.writePixels(image.height);
  }
  return stream.Take();
}

void WriteExr(const fs::path& path, const ImageRgbF& image) {
  std::vector<std::uint8_t> bytes;
  try {
    bytes = EncodeExr(image);
  } catch (const std::exception& e) {
    throw InputError(fmt::format("{}: cannot write EXR: {}", path.string(), e.what()));
  }
  WriteFile(path, bytes);
}

ImageRgbF ReadExr(const fs::path& path, const std::string& shown) {
  const std::string name = shown.empty() ? path.string() : shown;
  try {
    Imf::InputFile file(path.c_str());
    const Imath::Box2i window = file.header().dataWindow();
    const std::int64_t width = std::int64_t(window.max.x) - window.min.x + 1;
    const std::int64_t height = std::int64_t(window.max.y) - window.min.y + 1;
    if (width < 1 || height < 1 || width * height > (std::int64_t{1} << 26)) {
      throw InputError(fmt::format("{}: a {}x{} image; at most 2^26 pixels are read", name, width, height));
    }
    ImageRgbF image;
    image.width = int(width);
    image.height = int(height);
    image.pixels.resize(std::size_t(image.width) * image.height);
    Imf::FrameBuffer frame;
    const char* names[3] = {"R", "G", "B"};
    // OpenEXR addresses pixels by absolute coordinates: offset the base.
    char* base = reinterpret_cast<char*>(image.pixels.data()) -
                 (std::ptrdiff_t(window.min.x) + std::ptrdiff_t(window.min.y) * image.width) * sizeof(Vec3f);
    for (int c = 0; c < 3; ++c) {
      // A channel the file lacks reads as 0.
      frame.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), sizeof(Vec3f),
                                        sizeof(Vec3f) * image.width, 1, 1, 0.0));
    }
    file.setFrameBuffer(frame);
    file.readPixels(window.min.y, window.max.y);
    return image;
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(fmt::format("{}: cannot read EXR: {}", name, e.what()));
  }
}

void WritePfm(const fs::path& path, const ImageRgbF& image) {
  std::ofstream out(path, std::ios::binary);
  out << "PF\n" << image.width << ' ' << image.height << "\n-1.0\n";  // -1: little-endian
  for (int y = image.height - 1; y >= 0; --y) {  // PFM stores rows bottom to top
    out.write(reinterpret_cast<const char*>(&image.pixels[std::size_t(y) * image.width]),
              std::streamsize(sizeof(Vec3f)) * image.width);
  }
  if (!out) throw InputError(fmt::format("{}: cannot write the file", path.string()));
}

ImageRgbF ReadPfm(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string magic;
  ImageRgbF image;
  float scale = 0;
  in >> magic >> image.width >> image.height >> scale;
  in.get();
  if (!in || magic != "PF" || image.width <= 0 || image.height <= 0 || scale >= 0) {
    throw InputError(fmt::format("{}: not a little-endian RGB PFM file", path.string()));
  }
  image.pixels.resize(std::size_t(image.width) * image.height);
  for (int y = image.height - 1; y >= 0; --y) {
    in.read(reinterpret_cast<char*>(&image.pixels[std::size_t(y) * image.width]),
            std::streamsize(sizeof(Vec3f)) * image.width);
  }
  if (!in) throw InputError(fmt::format("{}: truncated PFM data", path.string()));
  return image;
}

}  // namespace cinevol
