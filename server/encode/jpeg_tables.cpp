// libjpeg's tables, read from a compressor it sets up, and the frame header.
#include "encode/jpeg_tables.h"

#include <algorithm>
#include <array>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>

#include "encode/libjpeg_errors.h"

namespace cinevol::jpeg {
namespace {

// A Huffman table as DHT writes it: code counts by length 1..16, then the symbols.
struct HuffmanSpec {
  std::uint8_t counts[16] = {};
  std::vector<std::uint8_t> symbols;
};

struct LibjpegTables {
  std::uint16_t quant[2][kBlockSamples] = {};  // natural order
  HuffmanSpec dc[2], ac[2];                    // luma, chroma
};

HuffmanSpec SpecOf(const JHUFF_TBL& table) {
  HuffmanSpec spec;
  int symbols = 0;
  for (int length = 1; length <= 16; ++length) {
    spec.counts[length - 1] = table.bits[length];
    symbols += table.bits[length];
  }
  spec.symbols.assign(table.huffval, table.huffval + symbols);
  return spec;
}

// What jpeg_set_quality(quality, force_baseline) leaves in a YCbCr compressor.
LibjpegTables ReadLibjpeg(int quality) {
  jpeg_compress_struct cinfo;
  JpegError err;
  cinfo.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = OnJpegError;
  if (setjmp(err.jump)) {
    jpeg_destroy_compress(&cinfo);
    throw std::runtime_error(std::string("libjpeg's tables: ") + err.message);
  }
  jpeg_create_compress(&cinfo);
  cinfo.in_color_space = JCS_YCbCr;
  cinfo.input_components = 3;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, quality, TRUE);
  LibjpegTables t;
  for (int c = 0; c < 2; ++c) {
    for (int i = 0; i < kBlockSamples; ++i) t.quant[c][i] = cinfo.quant_tbl_ptrs[c]->quantval[i];
    t.dc[c] = SpecOf(*cinfo.dc_huff_tbl_ptrs[c]);
    t.ac[c] = SpecOf(*cinfo.ac_huff_tbl_ptrs[c]);
  }
  jpeg_destroy_compress(&cinfo);
  return t;
}

// Canonical codes from the counts, as libjpeg's jpeg_make_c_derived_tbl.
HuffmanCodes CodesOf(const HuffmanSpec& spec) {
  HuffmanCodes codes;
  std::uint32_t code = 0;
  std::size_t next = 0;
  for (int length = 1; length <= 16; ++length, code <<= 1) {
    for (int i = 0; i < spec.counts[length - 1]; ++i, ++code, ++next) {
      codes.code[spec.symbols[next]] = std::uint16_t(code);
      codes.length[spec.symbols[next]] = std::uint8_t(length);
    }
  }
  return codes;
}

void Put16(std::vector<std::uint8_t>& out, int value) {
  out.push_back(std::uint8_t(value >> 8));
  out.push_back(std::uint8_t(value & 0xFF));
}

void PutMarker(std::vector<std::uint8_t>& out, std::uint8_t marker, int payload_bytes) {
  out.push_back(0xFF);
  out.push_back(marker);
  Put16(out, payload_bytes + 2);
}

void PutHuffman(std::vector<std::uint8_t>& out, int table_class, int id, const HuffmanSpec& spec) {
  out.push_back(std::uint8_t(table_class << 4 | id));
  out.insert(out.end(), std::begin(spec.counts), std::end(spec.counts));
  out.insert(out.end(), spec.symbols.begin(), spec.symbols.end());
}

// The quantisers in zigzag order, 8-bit precision: luma's as table 0, chroma's as 1.
std::vector<std::uint8_t> DqtSegment(const LibjpegTables& lib) {
  std::vector<std::uint8_t> out;
  PutMarker(out, 0xDB, 2 * (1 + kBlockSamples));
  for (int c = 0; c < 2; ++c) {
    out.push_back(std::uint8_t(c));
    for (int k = 0; k < kBlockSamples; ++k) out.push_back(std::uint8_t(lib.quant[c][NaturalOrder(k)]));
  }
  return out;
}

std::vector<std::uint8_t> DhtSegment(const LibjpegTables& lib) {
  std::size_t bytes = 0;
  for (int c = 0; c < 2; ++c) bytes += 2 * 17 + lib.dc[c].symbols.size() + lib.ac[c].symbols.size();
  std::vector<std::uint8_t> out;
  PutMarker(out, 0xC4, int(bytes));
  for (int c = 0; c < 2; ++c) {
    PutHuffman(out, 0, c, lib.dc[c]);
    PutHuffman(out, 1, c, lib.ac[c]);
  }
  return out;
}

QualityTables MakeTables(int quality) {
  const LibjpegTables lib = ReadLibjpeg(quality);
  QualityTables t;
  t.quality = quality;
  for (int c = 0; c < 2; ++c) {
    // Baseline quantisers (force_baseline: 1..255) fit the 16-bit divisors.
    for (int k = 0; k < kBlockSamples; ++k) t.coding.divisor[c][k] = MakeQuantDivisor(lib.quant[c][NaturalOrder(k)]);
    t.coding.dc[c] = CodesOf(lib.dc[c]);
    t.coding.ac[c] = CodesOf(lib.ac[c]);
  }
  t.dqt = DqtSegment(lib);
  t.dht = DhtSegment(lib);
  return t;
}

}  // namespace

const QualityTables& TablesFor(int quality) {
  quality = std::clamp(quality, 1, 100);
  static std::mutex mu;
  static std::array<std::unique_ptr<const QualityTables>, 101> tables;
  std::lock_guard lock(mu);
  if (!tables[quality]) tables[quality] = std::make_unique<const QualityTables>(MakeTables(quality));
  return *tables[quality];
}

std::vector<std::uint8_t> FrameHeader(int width, int height, ChromaSubsampling chroma, int quality,
                                      int mcus_per_interval) {
  if (width <= 0 || height <= 0 || width > 65535 || height > 65535) throw std::invalid_argument("JPEG frame size");
  if (mcus_per_interval < 1 || mcus_per_interval > 65535) throw std::invalid_argument("JPEG restart interval");
  const QualityTables& t = TablesFor(quality);
  const McuLayout layout = McuLayout::Of(width, height, chroma);
  std::vector<std::uint8_t> out = {0xFF, 0xD8};
  PutMarker(out, 0xE0, 14);  // JFIF 1.01, no density unit, 1:1, no thumbnail
  out.insert(out.end(), {'J', 'F', 'I', 'F', 0, 1, 1, 0, 0, 1, 0, 1, 0, 0});
  out.insert(out.end(), t.dqt.begin(), t.dqt.end());
  PutMarker(out, 0xC0, 15);  // baseline: precision, size, three components
  out.push_back(8);
  Put16(out, height);
  Put16(out, width);
  out.insert(out.end(), {3, 1, std::uint8_t(layout.luma_across << 4 | layout.luma_down), 0, 2, 0x11, 1, 3, 0x11, 1});
  out.insert(out.end(), t.dht.begin(), t.dht.end());
  PutMarker(out, 0xDD, 2);
  Put16(out, mcus_per_interval);
  PutMarker(out, 0xDA, 10);  // three components with their tables, the whole spectrum
  out.insert(out.end(), {3, 1, 0x00, 2, 0x11, 3, 0x11, 0, 63, 0});
  return out;
}

}  // namespace cinevol::jpeg
