// Enhanced multi-frame images: each frame's functional groups.
#include "io/formats/dicom/frames.h"

#include <fmt/format.h>
#include <gdcmReader.h>
#include <gdcmSequenceOfItems.h>

#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/error.h"
#include "io/formats/dicom/series.h"

namespace cinevol::formats::dicom {
namespace {

const gdcm::Tag kNumberOfFrames(0x0028, 0x0008);
const gdcm::Tag kSharedGroups(0x5200, 0x9229);
const gdcm::Tag kPerFrameGroups(0x5200, 0x9230);
const gdcm::Tag kPixelData(0x7fe0, 0x0010);
// The functional group macros read, and what each holds.
const gdcm::Tag kPlanePosition(0x0020, 0x9113);
const gdcm::Tag kImagePosition(0x0020, 0x0032);
const gdcm::Tag kPlaneOrientation(0x0020, 0x9116);
const gdcm::Tag kImageOrientation(0x0020, 0x0037);
const gdcm::Tag kPixelMeasures(0x0028, 0x9110);
const gdcm::Tag kPixelSpacing(0x0028, 0x0030);
const gdcm::Tag kSliceThickness(0x0018, 0x0050);
const gdcm::Tag kFrameContent(0x0020, 0x9111);
const gdcm::Tag kTemporalPositionIndex(0x0020, 0x9128);  // UL
const gdcm::Tag kCardiacSynchronization(0x0018, 0x9118);
const gdcm::Tag kNominalCardiacTriggerDelay(0x0020, 0x9153);  // FD
const gdcm::Tag kPixelValueTransformation(0x0028, 0x9145);
const gdcm::Tag kRescaleIntercept(0x0028, 0x1052);
const gdcm::Tag kRescaleSlope(0x0028, 0x1053);
const gdcm::Tag kFrameVoiLut(0x0028, 0x9132);
const gdcm::Tag kWindowCenter(0x0028, 0x1050);
const gdcm::Tag kWindowWidth(0x0028, 0x1051);

// Orientations and spacings closer than this are one.
constexpr double kSameGeometry = 1e-4;

const gdcm::ByteValue* BytesOf(const gdcm::DataSet& ds, const gdcm::Tag& tag) {
  return ds.FindDataElement(tag) ? ds.GetDataElement(tag).GetByteValue() : nullptr;
}

// A decimal string's numbers (DS, IS): empty where absent or not numbers.
std::vector<double> TextNumbers(const gdcm::DataSet& ds, const gdcm::Tag& tag) {
  const gdcm::ByteValue* v = BytesOf(ds, tag);
  return v ? Numbers(Trimmed(v->GetPointer(), v->GetLength())) : std::vector<double>{};
}

std::optional<double> TextNumber(const gdcm::DataSet& ds, const gdcm::Tag& tag) {
  const std::vector<double> v = TextNumbers(ds, tag);
  return v.size() == 1 ? std::optional<double>(v[0]) : std::nullopt;
}

// A binary value of `Type` (UL: uint32_t, FD: double), little endian as the
// transfer syntaxes cinevol reads store it; nothing where its length is not
// one value's or it is not finite.
template <class Type>
std::optional<double> BinaryNumber(const gdcm::DataSet& ds, const gdcm::Tag& tag) {
  const gdcm::ByteValue* v = BytesOf(ds, tag);
  if (!v || v->GetLength() != sizeof(Type)) return std::nullopt;
  Type value;
  std::memcpy(&value, v->GetPointer(), sizeof(Type));
  return std::isfinite(double(value)) ? std::optional<double>(double(value)) : std::nullopt;
}

// A frame's functional group macros: each in the frame's own item of the
// Per-frame Functional Groups Sequence, else in the shared item.
class FunctionalGroups {
 public:
  FunctionalGroups(const gdcm::DataSet& header) { shared_ = FirstItem(header, kSharedGroups); }

  // The (first item of the) macro `sequence` for `frame`'s item; null where
  // neither the frame nor the shared groups have it.
  const gdcm::DataSet* Macro(const gdcm::DataSet& frame, const gdcm::Tag& sequence) {
    if (const gdcm::DataSet* own = FirstItem(frame, sequence)) return own;
    return shared_ ? FirstItem(*shared_, sequence) : nullptr;
  }

  // The items of `sequence` in `ds` (held while this lives).
  const gdcm::SequenceOfItems* Items(const gdcm::DataSet& ds, const gdcm::Tag& sequence) {
    if (!ds.FindDataElement(sequence)) return nullptr;
    gdcm::SmartPointer<gdcm::SequenceOfItems> items = ds.GetDataElement(sequence).GetValueAsSQ();
    if (!items) return nullptr;
    held_.push_back(items);
    return items.GetPointer();
  }

 private:
  const gdcm::DataSet* FirstItem(const gdcm::DataSet& ds, const gdcm::Tag& sequence) {
    const gdcm::SequenceOfItems* items = Items(ds, sequence);
    return items && items->GetNumberOfItems() > 0 ? &items->GetItem(1).GetNestedDataSet() : nullptr;
  }

  // GDCM parses a sequence read as bytes anew at each GetValueAsSQ: what
  // points into one must keep it.
  std::vector<gdcm::SmartPointer<gdcm::SequenceOfItems>> held_;
  const gdcm::DataSet* shared_ = nullptr;
};

bool Alike(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::abs(a[i] - b[i]) > kSameGeometry) return false;
  }
  return true;
}

// The frame's numbers of `attribute` in the macro `macro`: refused where the
// frame has none, or not `count` of them.
std::vector<double> Required(FunctionalGroups& groups, const gdcm::DataSet& frame, const gdcm::Tag& macro,
                             const gdcm::Tag& attribute, std::size_t count, const char* what,
                             const std::string& where) {
  const gdcm::DataSet* m = groups.Macro(frame, macro);
  const std::vector<double> v = m ? TextNumbers(*m, attribute) : std::vector<double>{};
  if (v.size() != count) throw InputError(fmt::format("{} has no usable {}", where, what));
  return v;
}

}  // namespace

std::optional<MultiFrame> ReadMultiFrame(const std::string& file, const std::string& name) {
  gdcm::Reader reader;
  reader.SetFileName(file.c_str());
  if (!reader.ReadUpToTag(kPixelData)) return std::nullopt;
  const gdcm::DataSet& header = reader.GetFile().GetDataSet();
  const std::optional<double> count = TextNumber(header, kNumberOfFrames);
  if (!count || *count <= 1 || !header.FindDataElement(kPerFrameGroups)) return std::nullopt;

  FunctionalGroups groups(header);
  const gdcm::SequenceOfItems* items = groups.Items(header, kPerFrameGroups);
  const std::size_t n = items ? items->GetNumberOfItems() : 0;
  if (double(n) != *count) {
    throw InputError(
        fmt::format("{}: Number of Frames is {:g} and its Per-frame Functional Groups Sequence "
                    "holds {} items: not one a frame",
                    name, *count, n));
  }
  MultiFrame out;
  std::vector<double> orientation, spacing;
  for (std::size_t f = 0; f < n; ++f) {
    const gdcm::DataSet& frame = items->GetItem(f + 1).GetNestedDataSet();
    const std::string where = fmt::format("{} frame {}", name, f + 1);
    Frame& fr = out.frames.emplace_back();
    const std::vector<double> position =
        Required(groups, frame, kPlanePosition, kImagePosition, 3, "Image Position (Patient)", where);
    std::copy(position.begin(), position.end(), fr.position.begin());
    const std::vector<double> o =
        Required(groups, frame, kPlaneOrientation, kImageOrientation, 6, "Image Orientation (Patient)", where);
    const std::vector<double> s = Required(groups, frame, kPixelMeasures, kPixelSpacing, 2, "Pixel Spacing", where);
    if (f == 0) {
      orientation = o;
      spacing = s;
    } else if (!Alike(o, orientation) || !Alike(s, spacing)) {
      throw InputError(
          fmt::format("{}: frame {}'s {} differs from frame 1's; cinevol reads frames of one plane "
                      "orientation and pixel spacing",
                      name, f + 1, Alike(s, spacing) ? "orientation" : "pixel spacing"));
    }
    if (const gdcm::DataSet* content = groups.Macro(frame, kFrameContent)) {
      fr.temporal_position_index = BinaryNumber<std::uint32_t>(*content, kTemporalPositionIndex);
    }
    if (const gdcm::DataSet* cardiac = groups.Macro(frame, kCardiacSynchronization)) {
      fr.trigger_delay_ms = BinaryNumber<double>(*cardiac, kNominalCardiacTriggerDelay);
    }
    if (const gdcm::DataSet* rescale = groups.Macro(frame, kPixelValueTransformation)) {
      fr.rescale_slope = TextNumber(*rescale, kRescaleSlope).value_or(1.0);
      fr.rescale_intercept = TextNumber(*rescale, kRescaleIntercept).value_or(0.0);
    }
    if (f == 0) {
      const gdcm::DataSet* voi = groups.Macro(frame, kFrameVoiLut);
      const std::vector<double> centers = voi ? TextNumbers(*voi, kWindowCenter) : std::vector<double>{};
      const std::vector<double> widths = voi ? TextNumbers(*voi, kWindowWidth) : std::vector<double>{};
      if (!centers.empty() && !widths.empty() && widths[0] >= 1) out.window = {centers[0], widths[0]};
      const gdcm::DataSet* measures = groups.Macro(frame, kPixelMeasures);
      out.slice_thickness_mm = measures ? TextNumber(*measures, kSliceThickness).value_or(0.0) : 0.0;
    }
  }
  std::copy(orientation.begin(), orientation.end(), out.orientation.begin());
  out.pixel_spacing_mm = {spacing[1], spacing[0]};  // DICOM gives the row spacing (y) first
  if (!(out.pixel_spacing_mm[0] > 0 && out.pixel_spacing_mm[1] > 0)) {
    throw InputError(fmt::format("{}: Pixel Spacing {:g}\\{:g} is not above 0", name, spacing[0], spacing[1]));
  }
  return out;
}

}  // namespace cinevol::formats::dicom
