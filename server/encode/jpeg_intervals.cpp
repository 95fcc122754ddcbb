// The interval coder's loop on the CPU: each block quantised as it is coded.
#include "encode/jpeg_intervals.h"

#include <algorithm>
#include <stdexcept>

#include "encode/jpeg_tables.h"

namespace cinevol {

jpeg::FramePlanes PlanesOf(const ImageYcc8& image) {
  jpeg::FramePlanes planes;
  for (int c = 0; c < 3; ++c) planes.plane[c] = {image.Plane(c), image.PlaneWidth(c), image.PlaneHeight(c)};
  return planes;
}

std::vector<std::uint8_t> EncodeJpegInIntervals(const ImageYcc8& image, int quality, int mcus_per_interval) {
  if (image.width <= 0 || image.height <= 0 || !image.data ||
      image.size < YccBytes(image.width, image.height, image.chroma)) {
    throw std::invalid_argument("YCbCr planes do not match their size");
  }
  const jpeg::QualityTables& tables = jpeg::TablesFor(quality);
  const jpeg::McuLayout layout = jpeg::McuLayout::Of(image.width, image.height, image.chroma);
  const jpeg::FramePlanes planes = PlanesOf(image);
  std::vector<std::uint8_t> out = jpeg::FrameHeader(image.width, image.height, image.chroma, quality, mcus_per_interval);
  std::vector<std::uint8_t> interval(std::size_t(mcus_per_interval) * layout.blocks_per_mcu() * jpeg::kMaxBytesPerBlock);
  std::int16_t zigzag[jpeg::kBlockSamples];
  const int intervals = (layout.mcus() + mcus_per_interval - 1) / mcus_per_interval;
  for (int i = 0; i < intervals; ++i) {
    const int first_mcu = i * mcus_per_interval;
    const int mcus = std::min(mcus_per_interval, layout.mcus() - first_mcu);
    // Each block is quantised just before it is coded, into the one buffer.
    auto block = [&](int b) {
      const int per_mcu = layout.blocks_per_mcu();
      const jpeg::BlockPosition at = jpeg::PositionOf(layout, first_mcu + b / per_mcu, b % per_mcu);
      if (at.padding) return jpeg::QuantizedBlock{};
      const jpeg::QuantDivisor* divisors = tables.coding.divisor[at.component == 0 ? 0 : 1];
      const jpeg::PlaneView& plane = jpeg::PlaneOf(planes, at.component);
      return jpeg::QuantizedBlock{zigzag, jpeg::QuantizeBlock(plane, at.bx, at.by, divisors, zigzag)};
    };
    jpeg::BitSink sink(interval.data(), int(interval.size()));
    jpeg::CodeInterval(layout, mcus, tables.coding, block, sink);
    if (i > 0) out.insert(out.end(), {0xFF, jpeg::RestartMarker(i - 1)});
    out.insert(out.end(), interval.begin(), interval.begin() + sink.length());
  }
  out.insert(out.end(), std::begin(jpeg::kEndOfImage), std::end(jpeg::kEndOfImage));
  return out;
}

}  // namespace cinevol
