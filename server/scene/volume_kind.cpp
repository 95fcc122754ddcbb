// Judging a volume's kind. Metadata wins. Without it, CT shows itself by its
// values: HU by air near -1000; HU stored with the usual offset of 1024 by a
// soft-tissue peak near 1024 and bone far above it. Anything else (MR without
// metadata, 8-bit exports, micro-CT) cannot be told apart reliably by its
// histogram, and is "other": its default preset adapts to the histogram.
#include "scene/volume_kind.h"

#include <fmt/format.h>

namespace cinevol {
namespace {

// CT in HU has air at -1000 and reaches bone above +300; nothing else
// stored as HU-like values spans that.
bool LooksLikeHu(const Volume& v) { return v.min_value() <= -500.0f && v.max_value() >= 300.0f; }

VolumeKindJudgement FromModality(const Volume& v) {
  const std::string& m = v.metadata().modality;
  if (m == "CT") {
    if (v.metadata().value_unit == "HU" || LooksLikeHu(v)) return {v1::CT_HU, "modality CT, values in HU"};
    return {v1::CT_SCALED, fmt::format("modality CT, values {:g}..{:g} are not HU", v.min_value(), v.max_value())};
  }
  if (m == "MR") return {v1::MR, "modality MR"};
  return {v1::OTHER, fmt::format("modality {}", m)};
}

// The centre of the fullest histogram bin above the background (Otsu's
// threshold): soft tissue in CT.
float SubjectPeak(const ValueHistogram& h) {
  int best = h.BinOf(h.OtsuThreshold());
  for (int b = best; b < ValueHistogram::kBins; ++b) {
    if (h.counts[b] > h.counts[best]) best = b;
  }
  return h.BinStart(best) + 0.5f * h.BinWidth();
}

VolumeKindJudgement FromHistogram(const Volume& v) {
  if (LooksLikeHu(v)) {
    return {v1::CT_HU, fmt::format("no modality in the file; values {:g}..{:g} span CT's HU range (air at -1000)",
                                   v.min_value(), v.max_value())};
  }
  const float peak = SubjectPeak(v.histogram());
  if (v.min_value() >= -50.0f && peak >= 950.0f && peak <= 1150.0f && v.max_value() >= 1500.0f) {
    return {v1::CT_SCALED, fmt::format("no modality in the file; the peak above the background at {:.0f} and values "
                                       "up to {:g} look like CT in HU + 1024",
                                       peak, v.max_value())};
  }
  return {v1::OTHER, "no modality in the file and values that are not recognisably CT"};
}

}  // namespace

VolumeKindJudgement JudgeVolumeKind(const Volume& volume) {
  return volume.metadata().modality.empty() ? FromHistogram(volume) : FromModality(volume);
}

}  // namespace cinevol
