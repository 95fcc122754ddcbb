// Histogram statistics.
#include "core/value_histogram.h"

#include <algorithm>
#include <numeric>

#include "core/parallel_for.h"

namespace cinevol {

namespace {

template <class V>
ValueHistogram Count(ValuesView<V> values, float offset, float lo, float hi) {
  ValueHistogram h;
  h.min_value = lo;
  h.max_value = hi;
  h.counts.assign(ValueHistogram::kBins, 0);
  // Per-slab counts, summed: the same totals whatever thread ran what.
  constexpr std::size_t kSlab = std::size_t{1} << 22;
  std::vector<std::vector<std::uint64_t>> slabs((values.size() + kSlab - 1) / kSlab);
  ParallelFor(std::int64_t(slabs.size()), [&](std::int64_t s) {
    std::vector<std::uint64_t>& c = slabs[std::size_t(s)];
    c.assign(ValueHistogram::kBins, 0);
    const std::size_t end = std::min(values.size(), std::size_t(s + 1) * kSlab);
    for (std::size_t i = std::size_t(s) * kSlab; i < end; ++i) ++c[h.BinOf(float(values[i]) + offset)];
  });
  for (const auto& c : slabs) {
    for (int b = 0; b < ValueHistogram::kBins; ++b) h.counts[b] += c[b];
  }
  return h;
}

}  // namespace

ValueHistogram ValueHistogram::Of(ValuesView<float> values, float offset, float lo, float hi) {
  return Count(values, offset, lo, hi);
}

ValueHistogram ValueHistogram::Of(ValuesView<std::uint16_t> values, float offset, float lo, float hi) {
  return Count(values, offset, lo, hi);
}

int ValueHistogram::BinOf(float value) const {
  if (!(max_value > min_value)) return 0;
  const float t = (value - min_value) / (max_value - min_value);
  return std::clamp(static_cast<int>(t * float(kBins)), 0, kBins - 1);
}

float ValueHistogram::Percentile(double q, float from) const {
  if (counts.empty() || !(max_value > min_value)) return min_value;
  const int first = BinOf(from);
  const double total = std::accumulate(counts.begin() + first, counts.end(), 0.0);
  if (total <= 0) return max_value;
  const double wanted = std::clamp(q, 0.0, 1.0) * total;
  double below = 0;
  for (int b = first; b < kBins; ++b) {
    const double c = double(counts[b]);
    if (c > 0 && below + c >= wanted) return BinStart(b) + BinWidth() * float((wanted - below) / c);
    below += c;
  }
  return max_value;
}

float ValueHistogram::OtsuThreshold() const {
  if (counts.empty()) return min_value;
  double total = 0, sum = 0;
  for (int b = 0; b < kBins; ++b) {
    total += double(counts[b]);
    sum += double(counts[b]) * b;
  }
  double weight_low = 0, sum_low = 0, best = -1;
  int best_bin = 0;
  for (int b = 0; b < kBins - 1; ++b) {  // the split lies after bin b
    weight_low += double(counts[b]);
    sum_low += double(counts[b]) * b;
    const double weight_high = total - weight_low;
    if (weight_low <= 0 || weight_high <= 0) continue;
    const double mean_gap = sum_low / weight_low - (sum - sum_low) / weight_high;
    const double between = weight_low * weight_high * mean_gap * mean_gap;
    if (between > best) {
      best = between;
      best_bin = b;
    }
  }
  return BinStart(best_bin + 1);
}

}  // namespace cinevol
