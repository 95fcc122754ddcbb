// Codecs over libjpeg-turbo and libpng.
#include "encode/image_codecs.h"

#include <jpeglib.h>
#include <png.h>

#include <algorithm>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fstream>

#include <fmt/format.h>

#include "core/error.h"
#include "core/parallel_for.h"
#include "encode/libjpeg_errors.h"

namespace fs = std::filesystem;

namespace cinevol {
namespace {

void CheckImage(const ImageRgb8& image) {
  if (image.width <= 0 || image.height <= 0 ||
      image.bytes.size() != std::size_t(image.width) * image.height * 3) {
    throw std::invalid_argument("image buffer does not match its size");
  }
}

void CheckImage(const ImageYcc8& image) {
  if (image.width <= 0 || image.height <= 0 || !image.data ||
      image.size < YccBytes(image.width, image.height, image.chroma)) {
    throw std::invalid_argument("YCbCr planes do not match their size");
  }
}

// One JPEG from `space` input; write_lines(cinfo) feeds the started
// compressor all its lines. An error longjmps out of write_lines: it must
// hold no objects with destructors.
template <class WriteLines>
std::vector<std::uint8_t> CompressJpeg(int width, int height, J_COLOR_SPACE space, int quality,
                                       ChromaSubsampling chroma, const WriteLines& write_lines) {
  jpeg_compress_struct cinfo;
  JpegError err;
  cinfo.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = OnJpegError;
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  if (setjmp(err.jump)) {
    jpeg_destroy_compress(&cinfo);
    std::free(buffer);
    throw std::runtime_error(std::string("JPEG encoding failed: ") + err.message);
  }
  jpeg_create_compress(&cinfo);
  jpeg_mem_dest(&cinfo, &buffer, &size);
  cinfo.image_width = width;
  cinfo.image_height = height;
  cinfo.input_components = 3;
  cinfo.in_color_space = space;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, std::clamp(quality, 1, 100), TRUE);
  // Luma's sampling factors relative to chroma's (1x1) set the subsampling.
  cinfo.comp_info[0].h_samp_factor = chroma == ChromaSubsampling::k444 ? 1 : 2;
  cinfo.comp_info[0].v_samp_factor = chroma == ChromaSubsampling::k420 ? 2 : 1;
  cinfo.raw_data_in = space == JCS_YCbCr;  // planes come converted and downsampled
  jpeg_start_compress(&cinfo, TRUE);
  write_lines(cinfo);
  jpeg_finish_compress(&cinfo);
  jpeg_destroy_compress(&cinfo);
  std::vector<std::uint8_t> out(buffer, buffer + size);
  std::free(buffer);
  return out;
}

// The raw-data path takes one iMCU row (8 lines of each component per
// sampling factor) a call and reads whole 8x8 blocks. Each line goes through
// `scratch`, padded to whole blocks by repeating its last sample, and lines
// past a plane's bottom repeat its last line: libjpeg pads RGB input alike
// (expand_right_edge, expand_bottom_edge), so edge blocks encode the same.
// The compressor covers the image's luma rows from `first_line` (a whole
// number of iMCU rows) for its image_height.
void WriteRawLines(jpeg_compress_struct& cinfo, const ImageYcc8& image, int first_line,
                   std::vector<JSAMPLE>& scratch, std::vector<JSAMPROW>& lines) {
  int padded_width[3], lines_per_call[3];
  std::size_t scratch_size = 0, line_count = 0;
  for (int c = 0; c < 3; ++c) {
    padded_width[c] = int(cinfo.comp_info[c].width_in_blocks) * DCTSIZE;
    lines_per_call[c] = cinfo.comp_info[c].v_samp_factor * DCTSIZE;
    scratch_size += std::size_t(padded_width[c]) * lines_per_call[c];
    line_count += std::size_t(lines_per_call[c]);
  }
  scratch.resize(scratch_size);
  lines.resize(line_count);
  JSAMPARRAY planes[3];
  JSAMPLE* next_scratch = scratch.data();
  JSAMPROW* next_line = lines.data();
  for (int c = 0; c < 3; ++c) {
    planes[c] = next_line;
    for (int l = 0; l < lines_per_call[c]; ++l, next_scratch += padded_width[c]) *next_line++ = next_scratch;
  }
  const int first_call = first_line / lines_per_call[0];
  for (int call = first_call; cinfo.next_scanline < cinfo.image_height; ++call) {
    for (int c = 0; c < 3; ++c) {
      const int width = image.PlaneWidth(c), height = image.PlaneHeight(c);
      for (int l = 0; l < lines_per_call[c]; ++l) {
        const int y = std::min(call * lines_per_call[c] + l, height - 1);
        const JSAMPLE* src = image.Plane(c) + std::size_t(y) * width;
        std::copy(src, src + width, planes[c][l]);
        std::fill(planes[c][l] + width, planes[c][l] + padded_width[c], src[width - 1]);
      }
    }
    jpeg_write_raw_data(&cinfo, planes, JDIMENSION(lines_per_call[0]));
  }
}

// Luma rows [first_line, first_line + lines) of the planes as a JPEG of their own.
std::vector<std::uint8_t> EncodeBand(const ImageYcc8& image, int first_line, int lines, int quality) {
  std::vector<JSAMPLE> scratch;  // outside CompressJpeg's setjmp: an error frees them normally
  std::vector<JSAMPROW> rows;
  return CompressJpeg(image.width, lines, JCS_YCbCr, quality, image.chroma, [&](jpeg_compress_struct& cinfo) {
    WriteRawLines(cinfo, image, first_line, scratch, rows);
  });
}

// Where the parts of a JPEG that libjpeg wrote lie: the frame header's height
// field, the scan header, and the entropy-coded data between it and EOI.
struct JpegLayout {
  std::size_t height_at = 0, scan_header_at = 0, data_begin = 0, data_end = 0;
};

int BigEndian16(const std::vector<std::uint8_t>& b, std::size_t at) { return (b[at] << 8) | b[at + 1]; }

JpegLayout LayoutOf(const std::vector<std::uint8_t>& jpeg) {
  JpegLayout layout;
  for (std::size_t at = 2; at + 4 <= jpeg.size() && jpeg[at] == 0xFF;) {
    const int marker = jpeg[at + 1];
    const std::size_t length = std::size_t(BigEndian16(jpeg, at + 2));
    if (marker >= 0xC0 && marker <= 0xC2) layout.height_at = at + 5;  // SOFn: length, precision, height
    if (marker == 0xDA) {                                              // SOS: the data follows
      layout.scan_header_at = at;
      layout.data_begin = at + 2 + length;
      layout.data_end = jpeg.size() - 2;  // libjpeg ends with EOI, and wrote no restart markers
      break;
    }
    at += 2 + length;
  }
  if (layout.height_at == 0 || layout.data_begin == 0 || layout.data_begin > layout.data_end ||
      BigEndian16(jpeg, jpeg.size() - 2) != 0xFFD9) {
    throw std::runtime_error("JPEG encoding failed: libjpeg's output has an unexpected layout");
  }
  return layout;
}

// Joins bands encoded alone into one JPEG: every band after the first is a
// restart interval. A restart resets the DC predictors and pads the bit
// stream to a byte, as the start of a band's own scan does; the tables are
// the same in every band (one quality, libjpeg's standard Huffman tables), so
// the result decodes to exactly the pixels of a single encode.
std::vector<std::uint8_t> JoinBands(const std::vector<std::vector<std::uint8_t>>& bands, int height,
                                    int mcus_per_band) {
  const JpegLayout first = LayoutOf(bands[0]);
  std::vector<std::uint8_t> out(bands[0].begin(), bands[0].begin() + std::ptrdiff_t(first.scan_header_at));
  out[first.height_at] = std::uint8_t(height >> 8);
  out[first.height_at + 1] = std::uint8_t(height & 0xFF);
  const std::uint8_t restart_interval[] = {0xFF, 0xDD, 0x00, 0x04, std::uint8_t(mcus_per_band >> 8),
                                           std::uint8_t(mcus_per_band & 0xFF)};
  out.insert(out.end(), std::begin(restart_interval), std::end(restart_interval));
  out.insert(out.end(), bands[0].begin() + std::ptrdiff_t(first.scan_header_at),
             bands[0].begin() + std::ptrdiff_t(first.data_end));
  for (std::size_t i = 1; i < bands.size(); ++i) {
    const JpegLayout band = LayoutOf(bands[i]);
    out.push_back(0xFF);
    out.push_back(std::uint8_t(0xD0 + (i - 1) % 8));  // RST0..RST7, in turn
    out.insert(out.end(), bands[i].begin() + std::ptrdiff_t(band.data_begin),
               bands[i].begin() + std::ptrdiff_t(band.data_end));
  }
  out.push_back(0xFF);
  out.push_back(0xD9);
  return out;
}

}  // namespace

std::vector<std::uint8_t> EncodeJpeg(const ImageRgb8& image, int quality, ChromaSubsampling chroma) {
  CheckImage(image);
  return CompressJpeg(image.width, image.height, JCS_RGB, quality, chroma, [&](jpeg_compress_struct& cinfo) {
    while (cinfo.next_scanline < cinfo.image_height) {
      JSAMPROW row = const_cast<JSAMPROW>(&image.bytes[std::size_t(cinfo.next_scanline) * image.width * 3]);
      jpeg_write_scanlines(&cinfo, &row, 1);
    }
  });
}

std::vector<std::uint8_t> EncodeJpeg(const ImageYcc8& image, int quality, int bands) {
  CheckImage(image);
  // One iMCU row: 16 luma lines at 4:2:0, else 8; MCUs 16 or 8 pixels wide.
  const int mcu_height = image.chroma == ChromaSubsampling::k420 ? 16 : 8;
  const int mcu_width = image.chroma == ChromaSubsampling::k444 ? 8 : 16;
  const int mcu_rows = (image.height + mcu_height - 1) / mcu_height;
  const int mcus_per_row = (image.width + mcu_width - 1) / mcu_width;
  // A restart interval counts MCUs in 16 bits.
  const int max_rows_per_band = std::max(1, 65535 / mcus_per_row);
  int rows_per_band = (mcu_rows + std::clamp(bands, 1, mcu_rows) - 1) / std::clamp(bands, 1, mcu_rows);
  rows_per_band = std::min(rows_per_band, max_rows_per_band);
  bands = (mcu_rows + rows_per_band - 1) / rows_per_band;
  if (bands == 1 || mcus_per_row > 65535) return EncodeBand(image, 0, image.height, quality);

  // The bands run on the shared pool's free threads and this one: when the
  // pool is busy (the next frame rendering), this thread encodes them all.
  std::vector<std::vector<std::uint8_t>> encoded(static_cast<std::size_t>(bands));
  ParallelFor(bands, [&](std::int64_t band) {
    const int first_line = int(band) * rows_per_band * mcu_height;
    const int lines = std::min(rows_per_band * mcu_height, image.height - first_line);
    encoded[std::size_t(band)] = EncodeBand(image, first_line, lines, quality);
  }, bands);
  return JoinBands(encoded, image.height, rows_per_band * mcus_per_row);
}

namespace {

// Frames and images come from a server or a file: the size a header claims
// is allocated only up to the largest viewport.
constexpr std::uint64_t kMaxDecodedSide = 8192;

std::string DecodedSizeProblem(std::uint64_t width, std::uint64_t height) {
  if (width > 0 && height > 0 && width <= kMaxDecodedSide && height <= kMaxDecodedSide) return "";
  return fmt::format("{}x{} pixels, beyond {}x{}", width, height, kMaxDecodedSide, kMaxDecodedSide);
}

}  // namespace

ImageRgb8 DecodeJpeg(const std::vector<std::uint8_t>& bytes) {
  jpeg_decompress_struct cinfo;
  JpegError err;
  cinfo.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = OnJpegError;
  ImageRgb8 image;
  if (setjmp(err.jump)) {
    jpeg_destroy_decompress(&cinfo);
    throw InputError(std::string("not a decodable JPEG: ") + err.message);
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, bytes.data(), bytes.size());
  jpeg_read_header(&cinfo, TRUE);
  cinfo.out_color_space = JCS_RGB;
  if (const std::string problem = DecodedSizeProblem(cinfo.image_width, cinfo.image_height); !problem.empty()) {
    jpeg_destroy_decompress(&cinfo);
    throw InputError("not a decodable JPEG: " + problem);
  }
  jpeg_start_decompress(&cinfo);
  image.width = cinfo.output_width;
  image.height = cinfo.output_height;
  image.bytes.resize(std::size_t(image.width) * image.height * 3);
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = &image.bytes[std::size_t(cinfo.output_scanline) * image.width * 3];
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  return image;
}

std::vector<std::uint8_t> EncodePng(const ImageRgb8& image) {
  CheckImage(image);
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  png.width = image.width;
  png.height = image.height;
  png.format = PNG_FORMAT_RGB;
  png_alloc_size_t size = 0;
  if (!png_image_write_get_memory_size(png, size, 0, image.bytes.data(), 0, nullptr)) {
    throw std::runtime_error(std::string("PNG encoding failed: ") + png.message);
  }
  std::vector<std::uint8_t> out(size);
  if (!png_image_write_to_memory(&png, out.data(), &size, 0, image.bytes.data(), 0, nullptr)) {
    throw std::runtime_error(std::string("PNG encoding failed: ") + png.message);
  }
  out.resize(size);
  return out;
}

namespace {

// Decodes a PNG whose header `begin` has read; `what` names it in errors.
ImageRgb8 FinishPng(png_image& png, bool begun, const std::string& what) {
  if (!begun) throw InputError(fmt::format("{}: {}", what, png.message));
  if (const std::string problem = DecodedSizeProblem(png.width, png.height); !problem.empty()) {
    png_image_free(&png);
    throw InputError(fmt::format("{}: {}", what, problem));
  }
  png.format = PNG_FORMAT_RGB;
  ImageRgb8 image{int(png.width), int(png.height), std::vector<std::uint8_t>(PNG_IMAGE_SIZE(png))};
  if (!png_image_finish_read(&png, nullptr, image.bytes.data(), 0, nullptr)) {
    throw InputError(fmt::format("{}: {}", what, png.message));
  }
  return image;
}

png_image NewPngImage() {
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  return png;
}

}  // namespace

ImageRgb8 DecodePng(const std::vector<std::uint8_t>& bytes) {
  png_image png = NewPngImage();
  return FinishPng(png, png_image_begin_read_from_memory(&png, bytes.data(), bytes.size()), "not a decodable PNG");
}

ImageRgb8 ReadPng(const fs::path& path) {
  png_image png = NewPngImage();
  return FinishPng(png, png_image_begin_read_from_file(&png, path.c_str()), path.string());
}

void WriteFile(const fs::path& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  if (!out) throw InputError(fmt::format("{}: cannot write the file", path.string()));
}

}  // namespace cinevol
