// DICOM SEG inside the cage: DCMTK's dcmdata parses, cinevol checks every
// attribute it uses, counts the pixel data before they are read, and places
// the frames onto the target grid in two passes (the first to refuse SEGs
// that miss the volume before the parent reserves any memory, the second
// into that memory).
#include "io/readers/seg_reader.h"

// DCMTK's configuration first: its headers depend on it.
#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdatset.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcdict.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcitem.h>
#include <dcmtk/dcmdata/dcmetinf.h>
#include <dcmtk/dcmdata/dcsequen.h>
#include <dcmtk/dcmdata/dcxfer.h>
#include <dcmtk/oflog/oflog.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>

#include "core/error.h"
#include "core/parallel_for.h"
#include "core/volume.h"

namespace cinevol::reader {
namespace {

constexpr const char* kSegmentationStorage = "1.2.840.10008.5.1.4.1.1.66.4";
// Values longer than this stay in the file until asked for: the pixel data
// are counted before they are read.
constexpr Uint32 kMaxReadLength = 64 << 10;
// Pixels of all frames together, whatever the server's voxel limit.
constexpr std::uint64_t kMaxPixels = std::uint64_t{1} << 32;
// Direction cosines: unit length and orthogonal within this; frames' alike within kSameOrientation.
constexpr double kCosineTolerance = 1e-3;
constexpr double kSameOrientation = 1e-4;

using Vec3d = std::array<double, 3>;

double Dot(const Vec3d& a, const Vec3d& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

std::string Trimmed(const OFString& s) {
  std::string out(s.c_str(), s.length());
  while (!out.empty() && (out.back() == ' ' || out.back() == '\0')) out.pop_back();
  while (!out.empty() && out.front() == ' ') out.erase(out.begin());
  return out;
}

std::string Text(DcmItem& item, const DcmTagKey& tag) {
  OFString value;
  if (item.findAndGetOFStringArray(tag, value).bad()) return {};
  return Trimmed(value);
}

// `count` finite numbers of a DS (or FD) attribute; empty when any is missing or not a number.
std::vector<double> Numbers(DcmItem* item, const DcmTagKey& tag, unsigned count) {
  std::vector<double> out;
  if (!item) return out;
  for (unsigned i = 0; i < count; ++i) {
    Float64 v = 0;
    if (item->findAndGetFloat64(tag, v, i).bad() || !std::isfinite(v)) return {};
    out.push_back(v);
  }
  return out;
}

std::optional<long> Integer(DcmItem& item, const DcmTagKey& tag) {
  Uint16 u = 0;
  if (item.findAndGetUint16(tag, u).good()) return u;
  Sint32 s = 0;  // IS (Number of Frames)
  if (item.findAndGetSint32(tag, s).good()) return s;
  return std::nullopt;
}

// The item of functional group `group` for one frame: its own, else the shared one.
DcmItem* Group(DcmItem* per_frame, DcmItem* shared, const DcmTagKey& group) {
  DcmItem* item = nullptr;
  if (per_frame && per_frame->findAndGetSequenceItem(group, item, 0).good() && item) return item;
  item = nullptr;
  if (shared && shared->findAndGetSequenceItem(group, item, 0).good() && item) return item;
  return nullptr;
}

std::size_t Items(DcmItem& item, const DcmTagKey& tag) {
  DcmSequenceOfItems* sequence = nullptr;
  return item.findAndGetSequence(tag, sequence).good() && sequence ? sequence->card() : 0;
}

// The one file among `files` whose meta header names Segmentation Storage.
const DicomFile& ChooseSeg(const std::vector<DicomFile>& files, const std::string& shown) {
  if (files.size() == 1) return files[0];
  std::vector<const DicomFile*> segs;
  std::size_t dicom = 0;
  for (const DicomFile& f : files) {
    DcmFileFormat file;
    if (file.loadFile(f.path.c_str(), EXS_Unknown, EGL_noChange, 256, ERM_metaOnly).bad()) continue;
    OFString sop_class;
    if (file.getMetaInfo()->findAndGetOFString(DCM_MediaStorageSOPClassUID, sop_class).bad()) continue;
    ++dicom;
    if (Trimmed(sop_class) == kSegmentationStorage) segs.push_back(&f);
  }
  if (segs.empty()) {
    throw InputError(fmt::format("{}: no DICOM SEG among its {} files ({} of them DICOM)", shown, files.size(), dicom));
  }
  if (segs.size() > 1) {
    throw InputError(fmt::format("{}: {} DICOM SEGs ('{}', '{}'{}); name the one to load", shown, segs.size(),
                                 segs[0]->name, segs[1]->name, segs.size() > 2 ? ", ..." : ""));
  }
  return *segs[0];
}

struct Frame {
  int segment = 0;
  double u0 = 0, v0 = 0;  // its first pixel's centre along the row and column directions (mm)
  double along_normal = 0;
};

// What placing the frames found.
struct Placement {
  std::vector<bool> frame_met;  // some target voxel lies in it
  std::uint64_t overlaps = 0;   // voxels in more than one segment
};

class SegmentationRead final : public VolumeRead {
 public:
  SegmentationRead(const std::vector<DicomFile>& files, const Grid& target, const ReadOptions& options)
      : shown_(options.shown) {
    ReadTarget(target);
    const DicomFile& chosen = ChooseSeg(files, shown_);
    const OFCondition loaded =
        file_.loadFile(chosen.path.c_str(), EXS_Unknown, EGL_noChange, kMaxReadLength, ERM_autoDetect);
    if (loaded.bad()) throw InputError(fmt::format("{}: not DICOM that DCMTK reads ({})", shown_, loaded.text()));
    DcmDataset& data = *file_.getDataset();
    ReadImage(data, options);
    ReadSegments(data);
    ReadFrames(data);
    Plan();
    std::uint32_t outside = 0;
    for (const Frame& frame : frames_) outside += FrameMeetsVolume(frame) ? 0 : 1;
    if (outside == frames_.size()) {
      throw InputError(fmt::format(
          "{}: none of its {} frames lies in the volume's grid ({}x{}x{} voxels): it segments another region or "
          "another volume",
          shown_, frames_.size(), dims_[0], dims_[1], dims_[2]));
    }
    ReadPixels(data);
    FillHeader(Place(nullptr), outside);
  }

  void Read(void* memory, std::size_t bytes, int /*phase: one*/) override {
    if (bytes != voxels_ * sizeof(std::uint16_t)) throw std::runtime_error("memory of the wrong size for the labels");
    Place(static_cast<std::uint16_t*>(memory));
  }

 private:
  void ReadTarget(const Grid& t) {
    if (t.dims_size() != 3 || t.spacing_mm_size() != 3 || t.origin_mm_size() != 3 || t.direction_size() != 9) {
      throw std::runtime_error("a request without the volume's grid");
    }
    voxels_ = 1;
    for (int a = 0; a < 3; ++a) {
      dims_[a] = int(t.dims(a));
      if (dims_[a] < 1 || dims_[a] > kMaxVoxelsPerAxis) throw std::runtime_error("a target of impossible dimensions");
      voxels_ *= std::uint64_t(dims_[a]);
      origin_[a] = t.origin_mm(a);
      for (int r = 0; r < 3; ++r) axis_[a][r] = t.direction(3 * r + a) * t.spacing_mm(a);  // index axis a, in mm
    }
    if (voxels_ > kMaxVoxels) throw std::runtime_error("a target past the voxel limit");
    // The inverse of the matrix whose columns are axis_: patient offsets to voxel indices.
    const auto& m = axis_;
    const double det = m[0][0] * (m[1][1] * m[2][2] - m[2][1] * m[1][2]) -
                       m[1][0] * (m[0][1] * m[2][2] - m[2][1] * m[0][2]) +
                       m[2][0] * (m[0][1] * m[1][2] - m[1][1] * m[0][2]);
    if (!(std::abs(det) > 0)) throw std::runtime_error("a target whose axes are singular");
    for (int a = 0; a < 3; ++a) {
      const Vec3d& p = m[std::size_t((a + 1) % 3)];
      const Vec3d& q = m[std::size_t((a + 2) % 3)];
      index_from_patient_[std::size_t(a)] = {(p[1] * q[2] - p[2] * q[1]) / det, (p[2] * q[0] - p[0] * q[2]) / det,
                                             (p[0] * q[1] - p[1] * q[0]) / det};
    }
    target_ = t;
  }

  void ReadImage(DcmDataset& data, const ReadOptions& options) {
    const std::string sop_class = Text(data, DCM_SOPClassUID);
    if (sop_class != kSegmentationStorage) {
      throw InputError(fmt::format("{}: not a DICOM SEG: its SOP Class UID is '{}', not Segmentation Storage ({})",
                                   shown_, sop_class.substr(0, 64), kSegmentationStorage));
    }
    const DcmXfer xfer(data.getOriginalXfer());
    if (xfer.isEncapsulated() || xfer.getByteOrder() != EBO_LittleEndian) {
      throw InputError(
          fmt::format("{}: its transfer syntax, {}, is not read; cinevol reads SEGs in implicit or "
                      "explicit VR little endian, deflated or not",
                      shown_, xfer.getXferName()));
    }
    type_ = Text(data, DCM_SegmentationType);
    if (type_ != "BINARY" && type_ != "FRACTIONAL") {
      throw InputError(
          fmt::format("{}: Segmentation Type '{}'; cinevol reads BINARY and FRACTIONAL", shown_, type_.substr(0, 16)));
    }
    const auto rows = Integer(data, DCM_Rows), columns = Integer(data, DCM_Columns);
    const auto bits = Integer(data, DCM_BitsAllocated), frames = Integer(data, DCM_NumberOfFrames);
    const auto samples = Integer(data, DCM_SamplesPerPixel);
    if (!rows || !columns || *rows < 1 || *columns < 1) {
      throw InputError(fmt::format("{}: Rows and Columns must be at least 1", shown_));
    }
    if (!frames || *frames < 1) throw InputError(fmt::format("{}: Number of Frames must be at least 1", shown_));
    const long wanted_bits = type_ == "BINARY" ? 1 : 8;
    if (!bits || *bits != wanted_bits || (samples && *samples != 1)) {
      throw InputError(fmt::format("{}: a {} SEG has one sample of {} bit{} a pixel; this one says {} bits", shown_,
                                   type_, wanted_bits, wanted_bits > 1 ? "s" : "", bits.value_or(0)));
    }
    rows_ = int(*rows);
    columns_ = int(*columns);
    frame_count_ = std::uint64_t(*frames);
    const std::uint64_t pixels = frame_count_ * std::uint64_t(rows_) * std::uint64_t(columns_);
    if (pixels > std::min(kMaxPixels, options.max_voxels)) {
      throw InputError(fmt::format("{}: {} frames of {}x{} pixels = {} pixels exceeds this server's limit of {}",
                                   shown_, frame_count_, columns_, rows_, pixels,
                                   std::min(kMaxPixels, options.max_voxels)));
    }
    if (type_ == "FRACTIONAL") {
      const auto most = Integer(data, DCM_MaximumFractionalValue);
      if (!most || *most < 1 || *most > 255) {
        throw InputError(fmt::format("{}: a FRACTIONAL SEG needs a Maximum Fractional Value in [1, 255]", shown_));
      }
      max_fraction_ = int(*most);
    }
    frame_of_reference_ = Text(data, DCM_FrameOfReferenceUID);
    if (frame_of_reference_.empty()) {
      throw InputError(
          fmt::format("{}: it names no Frame of Reference UID (0020,0052), so its frames have no place in "
                      "patient space",
                      shown_));
    }
  }

  void ReadSegments(DcmDataset& data) {
    const std::size_t count = Items(data, DCM_SegmentSequence);
    if (count == 0) throw InputError(fmt::format("{}: its Segment Sequence (0062,0002) is empty or missing", shown_));
    if (count > std::size_t(kMaxSegments)) {
      throw InputError(fmt::format("{}: {} segments; cinevol reads at most {}", shown_, count, kMaxSegments));
    }
    for (std::size_t i = 0; i < count; ++i) {
      DcmItem* item = nullptr;
      data.findAndGetSequenceItem(DCM_SegmentSequence, item, int(i));
      const auto number = item ? Integer(*item, DCM_SegmentNumber) : std::nullopt;
      if (!number || *number < 1 || *number > 65535) {
        throw InputError(
            fmt::format("{}: segment {} of its Segment Sequence has no Segment Number in [1, 65535]", shown_, i + 1));
      }
      Segment& s = segments_[int(*number)];
      if (s.number() != 0) throw InputError(fmt::format("{}: segment number {} is given twice", shown_, *number));
      s.set_number(std::uint32_t(*number));
      s.set_label(Text(*item, DCM_SegmentLabel).substr(0, 256));
      Uint16 lab[3];
      bool has_lab = true;
      for (unsigned k = 0; k < 3; ++k)
        has_lab = has_lab && item->findAndGetUint16(DCM_RecommendedDisplayCIELabValue, lab[k], k).good();
      if (has_lab) s.mutable_cielab()->Add(lab, lab + 3);
    }
  }

  void ReadFrames(DcmDataset& data) {
    const std::size_t per_frame = Items(data, DCM_PerFrameFunctionalGroupsSequence);
    if (per_frame != frame_count_) {
      throw InputError(
          fmt::format("{}: Number of Frames is {} but its Per-frame Functional Groups Sequence holds {} "
                      "items",
                      shown_, frame_count_, per_frame));
    }
    DcmItem* shared = nullptr;
    data.findAndGetSequenceItem(DCM_SharedFunctionalGroupsSequence, shared, 0);
    std::vector<double> first_orientation, first_spacing;
    for (std::size_t f = 0; f < per_frame; ++f) {
      DcmItem* own = nullptr;
      data.findAndGetSequenceItem(DCM_PerFrameFunctionalGroupsSequence, own, int(f));
      Frame frame;
      DcmItem* identification = Group(own, shared, DCM_SegmentIdentificationSequence);
      const auto segment = identification ? Integer(*identification, DCM_ReferencedSegmentNumber) : std::nullopt;
      if (!segment)
        throw InputError(fmt::format("{}: frame {} names no segment (Segment Identification)", shown_, f + 1));
      if (!segments_.count(int(*segment))) {
        throw InputError(fmt::format("{}: frame {} names segment {}, which its Segment Sequence does not hold", shown_,
                                     f + 1, *segment));
      }
      frame.segment = int(*segment);
      const std::vector<double> position =
          Numbers(Group(own, shared, DCM_PlanePositionSequence), DCM_ImagePositionPatient, 3);
      const std::vector<double> orientation =
          Numbers(Group(own, shared, DCM_PlaneOrientationSequence), DCM_ImageOrientationPatient, 6);
      DcmItem* measures = Group(own, shared, DCM_PixelMeasuresSequence);
      const std::vector<double> spacing = Numbers(measures, DCM_PixelSpacing, 2);
      if (position.empty()) {
        throw InputError(
            fmt::format("{}: frame {} has no Image Position (Patient) (Plane Position Sequence)", shown_, f + 1));
      }
      if (orientation.empty() || spacing.empty()) {
        throw InputError(fmt::format("{}: frame {} has no {} (its functional groups)", shown_, f + 1,
                                     orientation.empty() ? "Image Orientation (Patient)" : "Pixel Spacing"));
      }
      if (f == 0) {
        first_orientation = orientation;
        first_spacing = spacing;
        for (const std::vector<double>& t :
             {Numbers(measures, DCM_SpacingBetweenSlices, 1), Numbers(measures, DCM_SliceThickness, 1)}) {
          stated_gaps_.push_back(t.empty() ? 0.0 : t[0]);
        }
        SetOrientation(orientation, spacing);
      }
      for (int k = 0; k < 6; ++k) {
        if (std::abs(orientation[k] - first_orientation[k]) > kSameOrientation) {
          throw InputError(
              fmt::format("{}: its frames lie in more than one orientation (frames 1 and {})", shown_, f + 1));
        }
      }
      for (int k = 0; k < 2; ++k) {
        if (std::abs(spacing[k] - first_spacing[k]) > 1e-6 * first_spacing[k]) {
          throw InputError(
              fmt::format("{}: its frames have more than one Pixel Spacing (frames 1 and {})", shown_, f + 1));
        }
      }
      const Vec3d p{position[0], position[1], position[2]};
      frame.u0 = Dot(p, row_);
      frame.v0 = Dot(p, column_);
      frame.along_normal = Dot(p, normal_);
      frames_.push_back(frame);
    }
  }

  // row_: along a row (columns increase), column_: down a column (rows increase).
  void SetOrientation(const std::vector<double>& o, const std::vector<double>& spacing) {
    row_ = {o[0], o[1], o[2]};
    column_ = {o[3], o[4], o[5]};
    if (std::abs(std::sqrt(Dot(row_, row_)) - 1) > kCosineTolerance ||
        std::abs(std::sqrt(Dot(column_, column_)) - 1) > kCosineTolerance ||
        std::abs(Dot(row_, column_)) > kCosineTolerance) {
      throw InputError(fmt::format("{}: its Image Orientation (Patient) is not two orthogonal unit vectors", shown_));
    }
    for (Vec3d* v : {&row_, &column_}) {
      const double length = std::sqrt(Dot(*v, *v));
      for (double& e : *v) e /= length;
    }
    normal_ = {row_[1] * column_[2] - row_[2] * column_[1], row_[2] * column_[0] - row_[0] * column_[2],
               row_[0] * column_[1] - row_[1] * column_[0]};
    row_spacing_ = spacing[0];     // between rows
    column_spacing_ = spacing[1];  // between columns
    for (double s : spacing) {
      if (!(s >= 1e-4 && s <= 1e4)) {
        throw InputError(
            fmt::format("{}: a Pixel Spacing of {:g} mm; cinevol reads spacings in [1e-4, 1e4] mm", shown_, s));
      }
    }
  }

  // The frames' planes along the normal, and the slab each covers.
  void Plan() {
    std::vector<std::size_t> order(frames_.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return frames_[a].along_normal < frames_[b].along_normal; });
    const double merge = 0.01 * std::min(row_spacing_, column_spacing_);
    for (std::size_t i : order) {
      if (planes_.empty() || frames_[i].along_normal - planes_.back() > merge) {
        planes_.push_back(frames_[i].along_normal);
        frames_of_plane_.emplace_back();
      }
      frames_of_plane_.back().push_back(int(i));
    }
    for (auto& list : frames_of_plane_) {  // the highest segment number written last: it wins where they overlap
      std::stable_sort(list.begin(), list.end(), [&](int a, int b) { return frames_[a].segment < frames_[b].segment; });
      const Frame& first = frames_[std::size_t(list.front())];
      bool shared = true;
      for (int f : list) {
        shared = shared && std::abs(frames_[std::size_t(f)].u0 - first.u0) < 1e-3 * column_spacing_ &&
                 std::abs(frames_[std::size_t(f)].v0 - first.v0) < 1e-3 * row_spacing_;
      }
      shared_origin_.push_back(shared);
    }
    double gap = 0;
    for (std::size_t i = 1; i < planes_.size(); ++i) {
      const double g = planes_[i] - planes_[i - 1];
      gap = gap == 0 ? g : std::min(gap, g);
    }
    const double between = stated_gaps_.size() == 2 ? stated_gaps_[0] : 0;
    const double thickness = stated_gaps_.size() == 2 ? stated_gaps_[1] : 0;
    if (gap > 0) {
      slice_spacing_ = between > 0 && between < gap ? between : gap;
    } else if (between > 0 || thickness > 0) {
      slice_spacing_ = between > 0 ? between : thickness;
    } else {
      // One plane and no thickness: as thick as the volume's voxels along its normal.
      slice_spacing_ = 0;
      for (int a = 0; a < 3; ++a) slice_spacing_ += std::abs(Dot(axis_[a], normal_));
      notes_.push_back(fmt::format("one plane of frames and no slice thickness: taken as {:.3g} mm", slice_spacing_));
    }
    if (!(slice_spacing_ >= 1e-4 && slice_spacing_ <= 1e4)) {
      throw InputError(fmt::format("{}: a slice spacing of {:g} mm; cinevol reads spacings in [1e-4, 1e4] mm", shown_,
                                   slice_spacing_));
    }
  }

  void ReadPixels(DcmDataset& data) {
    DcmElement* element = nullptr;
    if (data.findAndGetElement(DCM_PixelData, element).bad() || !element) {
      throw InputError(fmt::format("{}: it has no Pixel Data", shown_));
    }
    const std::uint64_t pixels = frame_count_ * std::uint64_t(rows_) * std::uint64_t(columns_);
    const std::uint64_t needed = type_ == "BINARY" ? (pixels + 7) / 8 : pixels;
    const std::uint64_t length = element->getLengthField();
    if (length < needed || length > needed + 1) {
      throw InputError(fmt::format("{}: its Pixel Data hold {} bytes, but {} frames of {}x{} {} pixels take {}", shown_,
                                   length, frame_count_, columns_, rows_, type_ == "BINARY" ? "1-bit" : "8-bit",
                                   needed));
    }
    Uint8* bytes = nullptr;
    if (element->getUint8Array(bytes).bad() || !bytes) {
      Uint16* words = nullptr;  // OW (implicit VR): little endian in memory on a little-endian host
      if (element->getUint16Array(words).bad() || !words) {
        throw InputError(fmt::format("{}: its Pixel Data cannot be read", shown_));
      }
      bytes = reinterpret_cast<Uint8*>(words);
    }
    pixels_ = bytes;
  }

  bool Set(std::size_t frame, std::size_t pixel) const {
    const std::size_t at = frame * std::size_t(rows_) * std::size_t(columns_) + pixel;
    if (max_fraction_ == 0) return (pixels_[at >> 3] >> (at & 7)) & 1;
    return 2 * int(pixels_[at]) >= max_fraction_;
  }

  // Whether the frame's rectangle (its pixels' extent) meets the volume's box
  // (its voxels' extent): separating axes, in the volume's index space.
  bool FrameMeetsVolume(const Frame& frame) const {
    const auto index = [&](double u, double v) {  // patient (row, column, normal coordinates) to voxel index
      Vec3d p, q{};
      for (int r = 0; r < 3; ++r) p[r] = u * row_[r] + v * column_[r] + frame.along_normal * normal_[r] - origin_[r];
      for (int r = 0; r < 3; ++r) q[r] = Dot(index_from_patient_[r], p);
      return q;
    };
    const double u0 = frame.u0 - 0.5 * column_spacing_, v0 = frame.v0 - 0.5 * row_spacing_;
    const double u1 = u0 + columns_ * column_spacing_, v1 = v0 + rows_ * row_spacing_;
    const std::array<Vec3d, 4> corners{index(u0, v0), index(u1, v0), index(u1, v1), index(u0, v1)};
    const auto minus = [](const Vec3d& a, const Vec3d& b) { return Vec3d{a[0] - b[0], a[1] - b[1], a[2] - b[2]}; };
    const auto cross = [](const Vec3d& a, const Vec3d& b) {
      return Vec3d{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    };
    const Vec3d e1 = minus(corners[1], corners[0]), e2 = minus(corners[3], corners[0]);
    std::vector<Vec3d> axes{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, cross(e1, e2)};
    for (const Vec3d& edge : {e1, e2}) {
      for (int a = 0; a < 3; ++a) axes.push_back(cross(edge, axes[std::size_t(a)]));
    }
    for (const Vec3d& axis : axes) {
      double low = 1e300, high = -1e300, centre = 0, reach = 0;
      for (const Vec3d& c : corners) {
        low = std::min(low, Dot(c, axis));
        high = std::max(high, Dot(c, axis));
      }
      for (int a = 0; a < 3; ++a) {
        centre += 0.5 * (dims_[a] - 1) * axis[std::size_t(a)];
        reach += 0.5 * dims_[a] * std::abs(axis[std::size_t(a)]);
      }
      if (high < centre - reach || low > centre + reach) return false;
    }
    return true;
  }

  // Calls `mark(pixel)` for every pixel of `frame` in its segment: bits
  // (eight zero pixels skipped at a time) or fractions at half the maximum.
  template <class Mark>
  void ForEachSet(std::size_t frame, Mark&& mark) const {
    const std::size_t n = std::size_t(rows_) * std::size_t(columns_), base = frame * n;
    if (max_fraction_ != 0) {
      for (std::size_t p = 0; p < n; ++p) {
        if (2 * int(pixels_[base + p]) >= max_fraction_) mark(p);
      }
      return;
    }
    for (std::size_t bit = base, end = base + n; bit < end;) {
      if ((bit & 7) == 0 && bit + 8 <= end && pixels_[bit >> 3] == 0) {
        bit += 8;
        continue;
      }
      if ((pixels_[bit >> 3] >> (bit & 7)) & 1) mark(bit - base);
      ++bit;
    }
  }

  // Each target voxel takes the segment of the nearest frame pixel in the
  // nearest plane within half a slice spacing; `out` (when given) gets it.
  // Where the volume's slices lie in the SEG's planes and a plane's frames
  // share their origin (as writers make them), the plane's frames are first
  // merged into one image of labels; else each voxel looks at each frame.
  Placement Place(std::uint16_t* out) const {
    const Vec3d o{origin_[0], origin_[1], origin_[2]};
    // Along the normal, the row and the column: affine in the voxel index.
    const double d0 = Dot(o, normal_), u0 = Dot(o, row_), v0 = Dot(o, column_);
    Vec3d dd, du, dv;
    for (int a = 0; a < 3; ++a) {
      dd[a] = Dot(axis_[a], normal_);
      du[a] = Dot(axis_[a], row_);
      dv[a] = Dot(axis_[a], column_);
    }
    const double half = 0.5 * slice_spacing_ * (1 + 1e-6);
    // Merged images take 3 bytes a pixel a thread: frames of up to 2^24 pixels are merged.
    const bool parallel = std::abs(dd[0]) * dims_[0] + std::abs(dd[1]) * dims_[1] < 1e-3 * slice_spacing_ &&
                          std::uint64_t(rows_) * std::uint64_t(columns_) <= (std::uint64_t{1} << 24);
    std::unique_ptr<std::atomic<bool>[]> met(new std::atomic<bool>[frames_.size()]());
    std::vector<std::uint64_t> overlaps(dims_[2], 0);
    const auto nearest_plane = [&](double d) -> int {
      auto it = std::lower_bound(planes_.begin(), planes_.end(), d);
      if (it == planes_.end() || (it != planes_.begin() && d - *(it - 1) < *it - d)) --it;
      return std::abs(d - *it) > half ? -1 : int(it - planes_.begin());
    };
    const auto pixel = [&](double u, double v, const Frame& frame, std::size_t* at) {
      const double c = std::floor((u - frame.u0) / column_spacing_ + 0.5);
      const double r = std::floor((v - frame.v0) / row_spacing_ + 0.5);
      if (!(c >= 0 && c < columns_ && r >= 0 && r < rows_)) return false;
      *at = std::size_t(r) * std::size_t(columns_) + std::size_t(c);
      return true;
    };
    ParallelFor(dims_[2], [&](std::int64_t z) {
      std::uint64_t overlapping = 0;
      const double zd = double(z);
      const int slice_plane =
          parallel ? nearest_plane(d0 + dd[0] * 0.5 * dims_[0] + dd[1] * 0.5 * dims_[1] + dd[2] * zd) : -1;
      if (parallel && slice_plane < 0) return;  // the whole slice between planes or beyond them
      if (parallel && shared_origin_[std::size_t(slice_plane)]) {
        const std::vector<int>& list = frames_of_plane_[std::size_t(slice_plane)];
        std::vector<std::uint16_t> image(std::size_t(rows_) * std::size_t(columns_), 0);
        std::vector<bool> overlapped(list.size() > 1 ? image.size() : 0, false);
        for (int f : list) {
          const auto segment = std::uint16_t(frames_[std::size_t(f)].segment);
          ForEachSet(std::size_t(f), [&](std::size_t p) {
            if (image[p] != 0 && image[p] != segment) overlapped[p] = true;
            image[p] = segment;
          });
        }
        const Frame& first = frames_[std::size_t(list.front())];
        bool hit = false;
        for (int y = 0; y < dims_[1]; ++y) {
          for (int x = 0; x < dims_[0]; ++x) {
            std::size_t at = 0;
            if (!pixel(u0 + du[0] * x + du[1] * y + du[2] * zd, v0 + dv[0] * x + dv[1] * y + dv[2] * zd, first, &at)) {
              continue;
            }
            hit = true;
            if (!overlapped.empty() && overlapped[at]) ++overlapping;
            if (out) out[(std::size_t(z) * dims_[1] + y) * dims_[0] + x] = image[at];
          }
        }
        for (int f : list) {
          if (hit) met[f].store(true, std::memory_order_relaxed);
        }
        overlaps[std::size_t(z)] = overlapping;
        return;
      }
      for (int y = 0; y < dims_[1]; ++y) {
        for (int x = 0; x < dims_[0]; ++x) {
          const int plane = parallel ? slice_plane : nearest_plane(d0 + dd[0] * x + dd[1] * y + dd[2] * zd);
          if (plane < 0) continue;
          const double u = u0 + du[0] * x + du[1] * y + du[2] * zd;
          const double v = v0 + dv[0] * x + dv[1] * y + dv[2] * zd;
          int label = 0;
          bool overlap = false;
          for (int f : frames_of_plane_[std::size_t(plane)]) {
            const Frame& frame = frames_[std::size_t(f)];
            std::size_t at = 0;
            if (!pixel(u, v, frame, &at)) continue;
            if (!met[f].load(std::memory_order_relaxed)) met[f].store(true, std::memory_order_relaxed);
            if (!Set(std::size_t(f), at)) continue;
            overlap = overlap || (label != 0 && label != frame.segment);
            label = frame.segment;
          }
          if (overlap) ++overlapping;
          if (out) out[(std::size_t(z) * dims_[1] + y) * dims_[0] + x] = std::uint16_t(label);
        }
      }
      overlaps[std::size_t(z)] = overlapping;
    });
    Placement placed;
    placed.frame_met.resize(frames_.size());
    for (std::size_t f = 0; f < frames_.size(); ++f) placed.frame_met[f] = met[f].load();
    for (std::uint64_t n : overlaps) placed.overlaps += n;
    return placed;
  }

  void FillHeader(const Placement& placed, std::uint32_t outside) {
    for (int a = 0; a < 3; ++a) header_.add_dims(std::uint32_t(dims_[a]));
    *header_.mutable_spacing_mm() = target_.spacing_mm();
    *header_.mutable_origin_mm() = target_.origin_mm();
    *header_.mutable_direction() = target_.direction();
    header_.set_voxel_type("uint16");
    header_.set_modality("SEG");
    header_.set_frame_of_reference_uid(frame_of_reference_);
    Segmentation& s = *header_.mutable_segmentation();
    for (const auto& [number, segment] : segments_) *s.add_segments() = segment;
    s.set_type(type_);
    s.set_frames(std::uint32_t(frames_.size()));
    s.set_frames_outside(outside);
    if (outside > 0)
      notes_.push_back(fmt::format("{} of its {} frames lie outside the volume", outside, frames_.size()));
    if (std::none_of(placed.frame_met.begin(), placed.frame_met.end(), [](bool met) { return met; })) {
      notes_.push_back("no voxel centre lies within half a slice of its frames: no voxel takes a segment");
    }
    if (placed.overlaps > 0) {
      notes_.push_back(fmt::format("{} voxels lie in more than one segment: each takes the highest segment number",
                                   placed.overlaps));
    }
    for (const std::string& note : notes_) *header_.add_notes() = note;
  }

  std::string shown_;
  DcmFileFormat file_;
  // The target grid: voxel (x, y, z) lies at origin_ + x axis_[0] + y axis_[1] + z axis_[2].
  Grid target_;
  int dims_[3] = {0, 0, 0};
  std::uint64_t voxels_ = 0;
  Vec3d origin_{};
  std::array<Vec3d, 3> axis_{};
  std::array<Vec3d, 3> index_from_patient_{};  // rows of the inverse of [axis_0 axis_1 axis_2]
  // The SEG.
  std::string type_, frame_of_reference_;
  int rows_ = 0, columns_ = 0;
  std::uint64_t frame_count_ = 0;
  int max_fraction_ = 0;  // 0: binary
  std::map<int, Segment> segments_;
  std::vector<Frame> frames_;
  Vec3d row_{}, column_{}, normal_{};
  double row_spacing_ = 1, column_spacing_ = 1, slice_spacing_ = 1;
  std::vector<double> stated_gaps_;  // the first frame's Spacing Between Slices and Slice Thickness (0: none)
  std::vector<double> planes_;       // ascending
  std::vector<std::vector<int>> frames_of_plane_;
  std::vector<bool> shared_origin_;  // a plane's frames all start at one point
  const Uint8* pixels_ = nullptr;
  std::vector<std::string> notes_;
};

}  // namespace

std::unique_ptr<VolumeRead> OpenSegmentation(const std::vector<DicomFile>& files, const Grid& target,
                                             const ReadOptions& options) {
  if (files.empty()) throw InputError(fmt::format("{}: no files", options.shown));
  return std::make_unique<SegmentationRead>(files, target, options);
}

void WarmUpSegmentations() {
  OFLog::configure(OFLogger::ERROR_LOG_LEVEL);
  if (!dcmDataDict.isDictionaryLoaded()) std::fputs("cinevol-reader: DCMTK's data dictionary did not load\n", stderr);
}

}  // namespace cinevol::reader
