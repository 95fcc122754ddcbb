// Baseline JPEG's per-block work, one source for the CPU and the GPU: the
// forward DCT and quantisation of one 8x8 block of a plane, and the Huffman
// coding of one restart interval of MCUs. The arithmetic is libjpeg's (its
// integer "islow" DCT, rounding division by the quantiser, its tables, edge
// blocks padded as its raw-data path pads them), so a frame coded here
// decodes to exactly the pixels libjpeg-turbo's encode of the same planes
// gives (tests/encode/jpeg_intervals_test.cpp). Restart intervals are coded
// independently (a GPU thread block each: pipeline/cuda_jpeg_encoder.cu; a
// loop on the CPU: encode/jpeg_intervals.h) and joined by RST markers.
#pragma once

#include <cstdint>

#include "core/hd.h"
#include "core/image.h"

namespace cinevol::jpeg {

inline constexpr int kBlockSide = 8;
inline constexpr int kBlockSamples = 64;

// The natural (row-major) index of the k-th coefficient in zigzag order.
// Called with constant k inside unrolled loops on the GPU, where the table
// folds away.
CINEVOL_HD constexpr int NaturalOrder(int k) {
  constexpr int kNatural[kBlockSamples] = {0,  1,  8,  16, 9,  2,  3,  10, 17, 24, 32, 25, 18, 11, 4,  5,
                                           12, 19, 26, 33, 40, 48, 41, 34, 27, 20, 13, 6,  7,  14, 21, 28,
                                           35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51,
                                           58, 59, 52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63};
  return kNatural[k];
}

// Division by a quantiser with rounding, as a multiplication: libjpeg-turbo's
// reciprocal (jcdctmgr.c, compute_reciprocal, 16-bit words), exact for the
// DCT's range (|value| < 2^15: tests check every value against division).
struct QuantDivisor {
  std::uint16_t reciprocal = 1;
  std::uint16_t correction = 0;  // half the divisor, + 1 where the reciprocal was rounded down
  std::uint16_t shift = 16;
  std::uint16_t divisor = 1;     // for the tests and the DQT marker's arithmetic
};

// The divisor of a DCT output for quantiser `q` (1..255): the islow DCT
// leaves its outputs scaled by 8, so the division is by 8q.
CINEVOL_HD QuantDivisor MakeQuantDivisor(int q) {
  const unsigned divisor = unsigned(q) * 8u;
  int b = 0;  // the highest set bit's index
  while ((divisor >> (b + 1)) != 0) ++b;
  int r = 16 + b;
  std::uint32_t reciprocal = (1u << r) / divisor;
  const std::uint32_t remainder = (1u << r) % divisor;
  unsigned correction = divisor / 2;
  if (remainder == 0) {  // a power of two: the reciprocal would need 17 bits
    reciprocal >>= 1;
    --r;
  } else if (remainder <= divisor / 2) {
    ++correction;
  } else {
    ++reciprocal;
  }
  return {std::uint16_t(reciprocal), std::uint16_t(correction), std::uint16_t(r), std::uint16_t(divisor)};
}

CINEVOL_HD int Quantize(int value, const QuantDivisor& d) {
  const std::uint32_t magnitude = std::uint32_t(value < 0 ? -value : value);
  const int q = int(((magnitude + d.correction) * d.reciprocal) >> d.shift);
  return value < 0 ? -q : q;
}

// libjpeg's jpeg_fdct_islow (jfdctint.c, Loeffler, Ligtenberg and Moschytz)
// in place on level-shifted samples, rows then columns; outputs scaled by 8.
// Every intermediate fits in 32 bits for 8-bit samples.
namespace islow {
inline constexpr int kConstBits = 13, kPass1Bits = 2;
inline constexpr int kFix0_298631336 = 2446, kFix0_390180644 = 3196, kFix0_541196100 = 4433,
                     kFix0_765366865 = 6270, kFix0_899976223 = 7373, kFix1_175875602 = 9633,
                     kFix1_501321110 = 12299, kFix1_847759065 = 15137, kFix1_961570560 = 16069,
                     kFix2_053119869 = 16819, kFix2_562915447 = 20995, kFix3_072711026 = 25172;

CINEVOL_HD int Descale(int x, int n) { return (x + (1 << (n - 1))) >> n; }

// One 1-D pass over the 8 values d[0], d[stride], ...: the row pass scales
// its outputs up by 2^kPass1Bits, the column pass takes that scale off again.
template <bool kRows>
CINEVOL_HD void Pass(int* d, int stride) {
  constexpr int kBits = kRows ? kConstBits - kPass1Bits : kConstBits + kPass1Bits;
  const int tmp0 = d[0] + d[7 * stride], tmp7 = d[0] - d[7 * stride];
  const int tmp1 = d[stride] + d[6 * stride], tmp6 = d[stride] - d[6 * stride];
  const int tmp2 = d[2 * stride] + d[5 * stride], tmp5 = d[2 * stride] - d[5 * stride];
  const int tmp3 = d[3 * stride] + d[4 * stride], tmp4 = d[3 * stride] - d[4 * stride];
  // Even part.
  const int tmp10 = tmp0 + tmp3, tmp13 = tmp0 - tmp3, tmp11 = tmp1 + tmp2, tmp12 = tmp1 - tmp2;
  if (kRows) {
    d[0] = (tmp10 + tmp11) * (1 << kPass1Bits);
    d[4 * stride] = (tmp10 - tmp11) * (1 << kPass1Bits);
  } else {
    d[0] = Descale(tmp10 + tmp11, kPass1Bits);
    d[4 * stride] = Descale(tmp10 - tmp11, kPass1Bits);
  }
  const int z1 = (tmp12 + tmp13) * kFix0_541196100;
  d[2 * stride] = Descale(z1 + tmp13 * kFix0_765366865, kBits);
  d[6 * stride] = Descale(z1 - tmp12 * kFix1_847759065, kBits);
  // Odd part.
  const int z5 = (tmp4 + tmp6 + tmp5 + tmp7) * kFix1_175875602;
  const int o1 = -(tmp4 + tmp7) * kFix0_899976223, o2 = -(tmp5 + tmp6) * kFix2_562915447;
  const int o3 = -(tmp4 + tmp6) * kFix1_961570560 + z5, o4 = -(tmp5 + tmp7) * kFix0_390180644 + z5;
  d[7 * stride] = Descale(tmp4 * kFix0_298631336 + o1 + o3, kBits);
  d[5 * stride] = Descale(tmp5 * kFix2_053119869 + o2 + o4, kBits);
  d[3 * stride] = Descale(tmp6 * kFix3_072711026 + o2 + o3, kBits);
  d[stride] = Descale(tmp7 * kFix1_501321110 + o1 + o4, kBits);
}
}  // namespace islow

CINEVOL_HD void ForwardDct(int* d) {
  CINEVOL_UNROLL
  for (int row = 0; row < kBlockSide; ++row) islow::Pass<true>(d + row * kBlockSide, 1);
  CINEVOL_UNROLL
  for (int column = 0; column < kBlockSide; ++column) islow::Pass<false>(d + column, kBlockSide);
}

// One plane of the frame, row after row, tightly packed.
struct PlaneView {
  const std::uint8_t* samples = nullptr;
  int width = 0, height = 0;
  // Past the right or bottom edge the edge sample repeats, as libjpeg pads.
  CINEVOL_HD int At(int x, int y) const {
    x = x < width ? x : width - 1;
    y = y < height ? y : height - 1;
    return samples[y * width + x];
  }
};

struct FramePlanes {
  PlaneView plane[3];  // Y, Cb, Cr
};

// Block (bx, by) of `plane`: its quantised coefficients in zigzag order into
// `zigzag`; returns which are not zero (bit k for coefficient k).
CINEVOL_HD std::uint64_t QuantizeBlock(const PlaneView& plane, int bx, int by, const QuantDivisor* divisors,
                                       std::int16_t* zigzag) {
  int d[kBlockSamples];
  CINEVOL_UNROLL
  for (int i = 0; i < kBlockSamples; ++i) d[i] = plane.At(bx * kBlockSide + i % 8, by * kBlockSide + i / 8) - 128;
  ForwardDct(d);
  std::uint64_t nonzero = 0;
  CINEVOL_UNROLL
  for (int k = 0; k < kBlockSamples; ++k) {
    const int q = Quantize(d[NaturalOrder(k)], divisors[k]);
    zigzag[k] = std::int16_t(q);
    nonzero |= std::uint64_t(q != 0) << k;
  }
  return nonzero;
}

// Where the blocks of a frame lie, MCU by MCU in scan order: luma's blocks
// of the MCU (2x2 at 4:2:0, 2x1 at 4:2:2, one at 4:4:4) row by row, then Cb,
// then Cr. Blocks past a component's last block of samples are padding
// (libjpeg's dummy blocks: the previous block's DC, no AC). Fields are
// scalars, not arrays, so that kernels keep them in registers.
struct McuLayout {
  int luma_across = 1, luma_down = 1;  // luma blocks per MCU
  int mcus_across = 0, mcus_down = 0;
  int luma_blocks_across = 0, luma_blocks_down = 0;      // blocks holding samples
  int chroma_blocks_across = 0, chroma_blocks_down = 0;  // likewise, for Cb and for Cr

  CINEVOL_HD static McuLayout Of(int width, int height, ChromaSubsampling chroma) {
    McuLayout m;
    m.luma_across = chroma == ChromaSubsampling::k444 ? 1 : 2;
    m.luma_down = chroma == ChromaSubsampling::k420 ? 2 : 1;
    m.mcus_across = (width + 8 * m.luma_across - 1) / (8 * m.luma_across);
    m.mcus_down = (height + 8 * m.luma_down - 1) / (8 * m.luma_down);
    m.luma_blocks_across = (width + 7) / 8;
    m.luma_blocks_down = (height + 7) / 8;
    m.chroma_blocks_across = (ChromaWidth(width, chroma) + 7) / 8;
    m.chroma_blocks_down = (ChromaHeight(height, chroma) + 7) / 8;
    return m;
  }
  CINEVOL_HD int luma_blocks() const { return luma_across * luma_down; }
  CINEVOL_HD int blocks_per_mcu() const { return luma_blocks() + 2; }
  CINEVOL_HD int mcus() const { return mcus_across * mcus_down; }
  CINEVOL_HD int component(int j) const { return j < luma_blocks() ? 0 : j - luma_blocks() + 1; }
};

struct BlockPosition {
  int component = 0, bx = 0, by = 0;
  bool padding = false;
};

// Block j of MCU `mcu`.
CINEVOL_HD BlockPosition PositionOf(const McuLayout& m, int mcu, int j) {
  const int mx = mcu % m.mcus_across, my = mcu / m.mcus_across;
  BlockPosition p;
  p.component = m.component(j);
  if (p.component == 0) {
    p.bx = mx * m.luma_across + j % m.luma_across;
    p.by = my * m.luma_down + j / m.luma_across;
    p.padding = p.bx >= m.luma_blocks_across || p.by >= m.luma_blocks_down;
  } else {
    p.bx = mx, p.by = my;
    p.padding = p.bx >= m.chroma_blocks_across || p.by >= m.chroma_blocks_down;
  }
  return p;
}

// Plane c of `planes`, chosen without indexing (kernels keep the three in registers).
CINEVOL_HD const PlaneView& PlaneOf(const FramePlanes& planes, int c) {
  return c == 0 ? planes.plane[0] : (c == 1 ? planes.plane[1] : planes.plane[2]);
}

// A Huffman table as the coder uses it: each symbol's code and its length in
// bits (0: the symbol has no code).
struct HuffmanCodes {
  std::uint16_t code[256] = {};
  std::uint8_t length[256] = {};
};

// What coding needs for one quality: each component class's divisors
// (luma, chroma) in zigzag order and Huffman tables (libjpeg's standard ones:
// encode/jpeg_tables.h builds them).
struct JpegTables {
  QuantDivisor divisor[2][kBlockSamples];
  HuffmanCodes dc[2], ac[2];
};

// Bits into bytes, most significant first, each 0xFF byte followed by a
// stuffed 0x00. Bytes past `capacity` are counted, not written: length() >
// capacity says the room was too small.
class BitSink {
 public:
  CINEVOL_HD BitSink(std::uint8_t* out, int capacity) : out_(out), capacity_(capacity) {}

  // The low `count` (<= 27) bits of `bits`.
  CINEVOL_HD void Put(std::uint32_t bits, int count) {
    pending_ = (pending_ << count) | (bits & ((1u << count) - 1u));
    pending_bits_ += count;
    while (pending_bits_ >= 8) {
      pending_bits_ -= 8;
      const std::uint8_t byte = std::uint8_t(pending_ >> pending_bits_);
      Emit(byte);
      if (byte == 0xFF) Emit(0);
    }
  }
  // Ends the interval on a byte boundary, padding with 1-bits (libjpeg's flush_bits).
  CINEVOL_HD void PadToByte() {
    Put(0x7F, 7);
    pending_bits_ = 0;
  }
  CINEVOL_HD int length() const { return length_; }

 private:
  CINEVOL_HD void Emit(std::uint8_t byte) {
    if (length_ < capacity_) out_[length_] = byte;
    ++length_;
  }

  std::uint8_t* out_;
  int capacity_;
  int length_ = 0;
  std::uint64_t pending_ = 0;
  int pending_bits_ = 0;
};

// The number of bits of a magnitude (JPEG's category): 0 for 0.
CINEVOL_HD int BitLength(std::uint32_t v) {
#if CINEVOL_DEVICE_PASS
  return 32 - __clz(v);
#else
  return v == 0 ? 0 : 32 - __builtin_clz(v);
#endif
}

CINEVOL_HD int LowestSetBit(std::uint64_t v) {
#if CINEVOL_DEVICE_PASS
  return __ffsll(static_cast<long long>(v)) - 1;
#else
  return __builtin_ctzll(v);
#endif
}

// A value's category code and its extra bits: the magnitude, or for a
// negative value its one's complement (libjpeg's temp2).
CINEVOL_HD void PutValue(int value, std::uint32_t category_code, int category_length, int category, BitSink& sink) {
  sink.Put(category_code, category_length);
  if (category > 0) sink.Put(std::uint32_t(value < 0 ? value - 1 : value), category);
}

// One block as libjpeg's encode_one_block codes it: the DC difference to
// `last_dc` (then updated), the AC coefficients as runs of zeros and values,
// EOB where the last ones are zero. `zigzag` is read only where `nonzero`
// (bits 1..63) says; `dc` is the block's DC.
CINEVOL_HD void CodeBlock(int dc, const std::int16_t* zigzag, std::uint64_t nonzero, int& last_dc,
                          const HuffmanCodes& dc_codes, const HuffmanCodes& ac_codes, BitSink& sink) {
  const int diff = dc - last_dc;
  last_dc = dc;
  const int dc_category = BitLength(std::uint32_t(diff < 0 ? -diff : diff));
  PutValue(diff, dc_codes.code[dc_category], dc_codes.length[dc_category], dc_category, sink);
  int previous = 0;
  for (std::uint64_t ac = nonzero & ~std::uint64_t(1); ac != 0; ac &= ac - 1) {
    const int k = LowestSetBit(ac);
    int run = k - previous - 1;
    for (; run > 15; run -= 16) sink.Put(ac_codes.code[0xF0], ac_codes.length[0xF0]);  // ZRL
    const int value = zigzag[k];
    const int category = BitLength(std::uint32_t(value < 0 ? -value : value));
    const int symbol = (run << 4) | category;
    PutValue(value, ac_codes.code[symbol], ac_codes.length[symbol], category, sink);
    previous = k;
  }
  if (previous < kBlockSamples - 1) sink.Put(ac_codes.code[0], ac_codes.length[0]);  // EOB
}

// The marker's second byte between intervals i and i + 1: RST0..RST7 in turn.
CINEVOL_HD std::uint8_t RestartMarker(int i) { return std::uint8_t(0xD0 + i % 8); }

// A block ready to code: its zigzag coefficients (null for padding) and which
// are not zero.
struct QuantizedBlock {
  const std::int16_t* zigzag = nullptr;
  std::uint64_t nonzero = 0;
};

// Codes `mcus` MCUs (their blocks in scan order) as one restart interval:
// the DC predictions start at 0 and the bits end on a byte. `block(i)` gives
// the interval's i-th block as a QuantizedBlock.
template <class BlockSource>
CINEVOL_HD void CodeInterval(const McuLayout& layout, int mcus, const JpegTables& tables, const BlockSource& block,
                             BitSink& sink) {
  int last_y = 0, last_cb = 0, last_cr = 0;
  // Padding repeats the DC before it: a difference of 0.
  auto code = [&](const QuantizedBlock& b, int& last_dc, int table) {
    const int dc = b.zigzag ? b.zigzag[0] : last_dc;
    CodeBlock(dc, b.zigzag, b.nonzero, last_dc, tables.dc[table], tables.ac[table], sink);
  };
  const int luma = layout.luma_blocks();
  for (int m = 0, i = 0; m < mcus; ++m) {
    for (int j = 0; j < luma; ++j) code(block(i++), last_y, 0);
    code(block(i++), last_cb, 1);
    code(block(i++), last_cr, 1);
  }
  sink.PadToByte();
}

}  // namespace cinevol::jpeg
