// The tables a frame coded by encode/jpeg_blocks.h uses, and the header that
// names them: libjpeg's own (jpeg_set_defaults, jpeg_set_quality), read from
// it once per quality, so that the coefficients and codes are those it would
// write.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image.h"
#include "encode/jpeg_blocks.h"

namespace cinevol::jpeg {

// One quality's tables: the coder's form (divisors, Huffman codes) and the
// DQT and DHT marker segments that give them to a decoder.
struct QualityTables {
  int quality = 0;
  JpegTables coding;
  std::vector<std::uint8_t> dqt, dht;
};

// libjpeg's baseline tables at `quality` (clamped to 1..100); built on first
// use, then shared. Thread-safe.
const QualityTables& TablesFor(int quality);

// Everything before the coded data of a frame whose restart intervals hold
// `mcus_per_interval` MCUs (1..65535): SOI, JFIF, DQT, SOF0, DHT, DRI, SOS.
std::vector<std::uint8_t> FrameHeader(int width, int height, ChromaSubsampling chroma, int quality,
                                      int mcus_per_interval);

// The end of every frame.
inline constexpr std::uint8_t kEndOfImage[2] = {0xFF, 0xD9};

// The most bytes one block's coded data can take: a DC difference (code and
// value: 11 + 11 bits), 63 AC values (16 + 10 bits each), three ZRLs (11
// bits each; runs add up to 63 at most), an EOB, every byte 0xFF and so
// stuffed, and an interval's padding. Real frames take a few percent of it.
inline constexpr int kMaxBytesPerBlock = 2 * ((22 + 63 * 26 + 3 * 11 + 16) / 8 + 1) + 1;

}  // namespace cinevol::jpeg
