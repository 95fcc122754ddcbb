// A volume's value histogram and what presets read from it: percentiles and
// the threshold that separates the subject from the air around it.
#pragma once

#include <cstdint>
#include <vector>

#include "core/voxel_memory.h"

namespace cinevol {

struct ValueHistogram {
  static constexpr int kBins = 256;
  float min_value = 0, max_value = 0;
  std::vector<std::uint64_t> counts;  // kBins equal-width bins over [min_value, max_value]

  // Counts `values` + `offset` (all inside [lo, hi]) into kBins bins.
  static ValueHistogram Of(ValuesView<float> values, float offset, float lo, float hi);
  static ValueHistogram Of(ValuesView<std::uint16_t> values, float offset, float lo, float hi);

  float BinWidth() const { return (max_value - min_value) / float(kBins); }
  float BinStart(int bin) const { return min_value + BinWidth() * float(bin); }
  int BinOf(float value) const;

  // The value below which a fraction q in [0, 1] of the voxels at or above
  // `from` lie (interpolated inside a bin).
  float Percentile(double q, float from) const;
  float Percentile(double q) const { return Percentile(q, min_value); }

  // Otsu's threshold: the bin edge that best splits the histogram in two
  // classes (between-class variance), i.e. background from subject.
  float OtsuThreshold() const;
};

}  // namespace cinevol
