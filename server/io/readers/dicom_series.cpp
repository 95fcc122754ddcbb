// DICOM series from a folder: GDCM scans the headers, cinevol groups, sorts
// and checks the slices, ITK/GDCM decodes the pixels (JPEG 2000 and other
// compressed transfer syntaxes included) and applies rescale slope/intercept.
#include <gdcmDicts.h>
#include <gdcmGlobal.h>
#include <gdcmScanner.h>
#include <itkGDCMImageIO.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "core/error.h"
#include "core/volume.h"
#include "core/voxel_memory.h"
#include "io/file_checks.h"
#include "io/readers/formats.h"
#include "io/readers/itk_image.h"

namespace fs = std::filesystem;

namespace cinevol {
namespace {

const gdcm::Tag kSeriesUid(0x0020, 0x000e);
const gdcm::Tag kSeriesDescription(0x0008, 0x103e);
const gdcm::Tag kModality(0x0008, 0x0060);
const gdcm::Tag kImagePosition(0x0020, 0x0032);
const gdcm::Tag kImageOrientation(0x0020, 0x0037);
const gdcm::Tag kRows(0x0028, 0x0010);
const gdcm::Tag kColumns(0x0028, 0x0011);
const gdcm::Tag kSliceThickness(0x0018, 0x0050);
const gdcm::Tag kPhotometric(0x0028, 0x0004);
const gdcm::Tag kRescaleIntercept(0x0028, 0x1052);
const gdcm::Tag kRescaleSlope(0x0028, 0x1053);

// Slices whose positions along the normal differ by more than this fraction
// of the typical gap count as unevenly spaced.
constexpr double kGapTolerance = 0.01;
// Slice stacks sheared by more than this (degrees) count as gantry tilt, and
// are resampled.
constexpr double kMaxTiltDeg = 0.1;

struct Scan {
  gdcm::Scanner scanner;
  std::vector<std::string> dicom_files;  // paths of files that parsed as DICOM
  std::size_t files_seen = 0;
  std::map<std::string, std::string> names;  // path -> the file's path under the folder
  std::string shown;                         // what messages call the folder

  // What messages call a file in the folder: its path under `shown`. Where
  // `shown` ends in a quoted folder ("path 'DIR'"), the file's whole path is
  // quoted ('DIR/14.dcm'), not the folder alone ('DIR'/14.dcm).
  std::string Name(const std::string& file) const {
    const auto it = names.find(file);
    const std::string under = it == names.end() ? std::string("?") : it->second;
    const std::size_t open = shown.ends_with('\'') ? shown.rfind('\'', shown.size() - 2) : std::string::npos;
    const std::string folder = open == std::string::npos ? shown : shown.substr(open + 1, shown.size() - open - 2);
    const std::string path = folder + (folder.ends_with('/') ? "" : "/") + under;
    return open == std::string::npos ? path : "'" + path + "'";
  }
};

// GDCM trusts a DICOM file's structure: it asserts (aborting the process;
// Debian keeps its asserts) on a file meta element whose VR it does not know,
// and allocates whatever length an element declares (4 GiB in a 1 KiB file).
// So a file's elements are walked here first, headers only, nested sequences
// included: every VR known, every defined length inside the file. A file
// that fails is not handed to GDCM (it counts as not DICOM).
class DicomWalk {
 public:
  explicit DicomWalk(std::FILE* f, std::int64_t size) : f_(f), size_(size) {}

  bool File() {
    std::uint8_t magic[4];
    std::int64_t at = 0;
    if (size_ >= 132 && Read(128, magic, 4) && std::memcmp(magic, "DICM", 4) == 0) {
      at = 132;
      // The file meta group: explicit VR little endian, group 0002.
      std::uint8_t h[4];
      while (at + 8 <= size_ && Read(at, h, 2) && U16(h) == 0x0002) {
        if (!Element(at, size_, true, 0, true)) return false;
      }
      // GDCM asserts reading a meta group that the file ends in (found by
      // fuzz_volume); a file without a data set holds no image anyway.
      if (at == size_) return false;
      // A data set in big-endian or deflated encoding is not walked here (the
      // walk reads little-endian bytes as they stand): GDCM reads it in the
      // cage, where its failure is the load's alone.
      if (transfer_syntax_ == "1.2.840.10008.1.2.2" || transfer_syntax_ == "1.2.840.10008.1.2.1.99") return true;
    }
    if (at == size_) return true;
    // The data set: explicit VR when the bytes after the first tag read as a
    // VR (GDCM guesses the same way when the meta group is absent or wrong).
    std::uint8_t h[6];
    const bool explicit_vr = at + 6 <= size_ && Read(at, h, 6) && IsVr(h + 4);
    while (at < size_) {
      if (!Element(at, size_, explicit_vr, 0, false)) return false;
    }
    return PixelModuleIsSound();
  }

 private:
  static unsigned U16(const std::uint8_t* b) { return unsigned(b[0]) | unsigned(b[1]) << 8; }
  static std::uint32_t U32(const std::uint8_t* b) { return std::uint32_t(U16(b)) | std::uint32_t(U16(b + 2)) << 16; }
  static bool IsVr(const std::uint8_t* v) {
    static const char* const kVrs[] = {"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FD", "FL", "IS", "LO",
                                       "LT", "OB", "OD", "OF", "OL", "OW", "PN", "SH", "SL", "SQ", "SS",
                                       "ST", "TM", "UC", "UI", "UL", "UN", "UR", "US", "UT"};
    return std::any_of(std::begin(kVrs), std::end(kVrs), [&](const char* k) { return std::memcmp(k, v, 2) == 0; });
  }
  static bool IsLongVr(const std::uint8_t* v) {
    static const char* const kLong[] = {"OB", "OD", "OF", "OL", "OW", "SQ", "UC", "UN", "UR", "UT"};
    return std::any_of(std::begin(kLong), std::end(kLong), [&](const char* k) { return std::memcmp(k, v, 2) == 0; });
  }
  bool Read(std::int64_t at, std::uint8_t* out, std::size_t n) {
    return at >= 0 && at + std::int64_t(n) <= size_ && std::fseek(f_, long(at), SEEK_SET) == 0 &&
           std::fread(out, 1, n, f_) == n;
  }

  // One element at `at` (advanced past it) that must end by `end`.
  bool Element(std::int64_t& at, std::int64_t end, bool explicit_vr, int depth, bool meta) {
    if (depth > 16 || ++elements_ > 200000) return false;
    std::uint8_t h[12];
    if (at + 8 > end || !Read(at, h, 8)) return false;
    const unsigned group = U16(h), element = U16(h + 2);
    std::uint32_t length;
    bool sequence = false;
    if (group == 0xfffe) {  // item or delimiter: tag and a 4-byte length, never a VR
      length = U32(h + 4);
      at += 8;
      if (element == 0xe00d || element == 0xe0dd) return length == 0;
      if (element != 0xe000) return false;
      if (length == 0xffffffffu) return Items(at, end, explicit_vr, depth + 1, 0xe00d);
      if (length > std::uint64_t(end - at)) return false;
      const std::int64_t item_end = at + length;
      while (at < item_end) {
        if (!Element(at, item_end, explicit_vr, depth + 1, false)) return false;
      }
      return true;
    }
    if (meta && group != 0x0002) return false;
    if (explicit_vr) {
      if (!IsVr(h + 4)) return false;
      sequence = std::memcmp(h + 4, "SQ", 2) == 0;
      if (IsLongVr(h + 4)) {
        if (at + 12 > end || !Read(at + 8, h + 8, 4)) return false;
        length = U32(h + 8);
        at += 12;
      } else {
        length = U16(h + 6);
        at += 8;
      }
    } else {
      length = U32(h + 4);
      at += 8;
    }
    // GDCM asserts on a sequence or an undefined length in the file meta
    // group (found by fuzz_volume); the standard allows neither there.
    if (meta && (sequence || length == 0xffffffffu)) return false;
    const bool pixel_data = group == 0x7fe0 && element == 0x0010;
    const bool un = explicit_vr && std::memcmp(h + 4, "UN", 2) == 0;
    // GDCM asserts on Pixel Data of another VR, and on an explicit VR that
    // its dictionary does not allow for a public element (Rows as OW).
    if (explicit_vr && pixel_data && std::memcmp(h + 4, "OB", 2) != 0 && std::memcmp(h + 4, "OW", 2) != 0 && !un) {
      return false;
    }
    if (explicit_vr && !meta && !un && !VrFitsDictionary(group, element, h + 4)) return false;
    if (length == 0xffffffffu) {
      // Undefined lengths: encapsulated Pixel Data (fragments, each an item
      // of plain bytes), or a sequence; GDCM asserts on any other, and on
      // nested UN sequences it repairs otherwise than this walk reads them.
      if (pixel_data) return Fragments(at, end, depth == 0);
      if (explicit_vr && !sequence && !(un && depth == 0)) return false;
      return Items(at, end, explicit_vr && !un, depth + 1, 0xe0dd);  // implicit VR inside an undefined-length UN
    }
    if (length > std::uint64_t(end - at)) return false;
    if (depth > 0 && length % 2 != 0) return false;  // the standard's even lengths; GDCM asserts in items
    if (depth == 0) Remember(group, element, at, length, pixel_data);
    if (meta && element == 0x0010 && length <= 64) {  // (0002,0010) Transfer Syntax UID
      transfer_syntax_.assign(length, '\0');
      if (!Read(at, reinterpret_cast<std::uint8_t*>(transfer_syntax_.data()), length)) return false;
      while (!transfer_syntax_.empty() && (transfer_syntax_.back() == '\0' || transfer_syntax_.back() == ' ')) {
        transfer_syntax_.pop_back();
      }
    }
    // GDCM asserts that Samples per Pixel is 1, 3 or 4 (an abort, found by
    // fuzz_volume), in any image, icons included.
    if (group == 0x0028 && element == 0x0002 && !meta) {
      std::uint8_t v[2];
      if (length < 2 || !Read(at, v, 2) || (U16(v) != 1 && U16(v) != 3 && U16(v) != 4)) return false;
    }
    at += length;
    return true;
  }

  // Items of plain bytes up to the sequence delimiter, which is consumed: the
  // basic offset table, then at least one fragment (GDCM asserts on none).
  // The top-level image's first fragment is remembered, for its codec's check.
  bool Fragments(std::int64_t& at, std::int64_t end, bool top_level) {
    for (int items = 0; at + 8 <= end; ++items) {
      std::uint8_t h[8];
      if (!Read(at, h, 8) || U16(h) != 0xfffe || ++elements_ > 200000) return false;
      at += 8;
      if (U16(h + 2) == 0xe0dd) return items >= 2;
      const std::uint32_t length = U32(h + 4);
      if (U16(h + 2) != 0xe000 || length > std::uint64_t(end - at)) return false;
      if (top_level && items == 1) {
        pixels_.first_fragment = at;
        pixels_.fragment_length = length;
      }
      at += length;
    }
    return false;
  }

  // What GDCM's typed reads take from the dictionary: a public element's
  // explicit VR must be one it accepts for the tag.
  static bool VrFitsDictionary(unsigned group, unsigned element, const std::uint8_t* vr) {
    if (group % 2 != 0) return true;  // private: no dictionary entry
    const gdcm::DictEntry& entry =
        gdcm::Global::GetInstance().GetDicts().GetPublicDict().GetDictEntry(gdcm::Tag(std::uint16_t(group),
                                                                                      std::uint16_t(element)));
    const gdcm::VR expected = entry.GetVR();
    if (expected == gdcm::VR::INVALID) return true;  // not in the dictionary
    const char name[3] = {char(vr[0]), char(vr[1]), 0};
    return expected.Compatible(gdcm::VR(gdcm::VR::GetVRType(name)));
  }

  // The top-level image's pixel module, as the walk passes it.
  struct PixelModule {
    int rows = -1, columns = -1, samples = -1, bits_allocated = -1, bits_stored = -1;
    bool pixel_data = false;
    std::int64_t first_fragment = -1;  // encapsulated: the first fragment after the offset table
    std::uint32_t fragment_length = 0;
  };

  void Remember(unsigned group, unsigned element, std::int64_t at, std::uint32_t length, bool pixel_data) {
    if (pixel_data) pixels_.pixel_data = true;
    if (group != 0x0028 || length < 2) return;
    std::uint8_t v[2];
    if (!Read(at, v, 2)) return;
    const int value = int(U16(v));
    switch (element) {
      case 0x0002: pixels_.samples = value; break;
      case 0x0010: pixels_.rows = value; break;
      case 0x0011: pixels_.columns = value; break;
      case 0x0100: pixels_.bits_allocated = value; break;
      case 0x0101: pixels_.bits_stored = value; break;
      default: break;
    }
  }

  // GDCM asserts on a Bits Allocated it has no codec for (12), on Bits
  // Stored above Bits Allocated or missing, and decodes a JPEG 2000 or RLE
  // stream that disagrees with the header past its buffers. So the image's
  // pixel module must hold together, and a compressed image's first fragment
  // must describe the image the header does.
  bool PixelModuleIsSound() {
    const PixelModule& p = pixels_;
    if (!p.pixel_data) return true;
    const bool bits_known = p.bits_allocated == 1 || p.bits_allocated == 8 || p.bits_allocated == 16 ||
                            p.bits_allocated == 32 || p.bits_allocated == 64;
    if (!bits_known || p.bits_stored < 1 || p.bits_stored > p.bits_allocated) return false;
    if (p.first_fragment < 0) return true;  // not encapsulated
    const bool j2k = transfer_syntax_.rfind("1.2.840.10008.1.2.4.9", 0) == 0;
    const bool rle = transfer_syntax_ == "1.2.840.10008.1.2.5";
    if (j2k) return J2kFitsHeader();
    if (rle) return RleFitsHeader();
    return true;
  }

  static std::uint32_t Be32(const std::uint8_t* b) {
    return std::uint32_t(b[0]) << 24 | std::uint32_t(b[1]) << 16 | std::uint32_t(b[2]) << 8 | b[3];
  }

  // A JPEG 2000 code stream (or a JP2 file's 'jp2c' box) whose SIZ marker
  // gives the header's columns, rows and samples.
  bool J2kFitsHeader() {
    const std::size_t n = std::min<std::size_t>(pixels_.fragment_length, 4096);
    std::vector<std::uint8_t> b(n);
    if (n < 42 || !Read(pixels_.first_fragment, b.data(), n)) return false;
    std::size_t c = 0;  // where the code stream starts
    if (b[0] != 0xff || b[1] != 0x4f) {
      const auto box = std::search(b.begin(), b.end(), std::begin("jp2c"), std::begin("jp2c") + 4);
      if (box == b.end()) return false;
      c = std::size_t(box - b.begin()) + 4;
    }
    if (c + 42 > n || b[c] != 0xff || b[c + 1] != 0x4f || b[c + 2] != 0xff || b[c + 3] != 0x51) return false;
    const std::uint8_t* siz = b.data() + c + 4;  // Lsiz, Rsiz, Xsiz, Ysiz, XOsiz, YOsiz, ..., Csiz
    const std::int64_t width = std::int64_t(Be32(siz + 4)) - Be32(siz + 12);
    const std::int64_t height = std::int64_t(Be32(siz + 8)) - Be32(siz + 16);
    const int components = int(siz[36]) << 8 | siz[37];
    return width == pixels_.columns && height == pixels_.rows && components == pixels_.samples;
  }

  // An RLE fragment's header: 1 to 15 segments, one per byte of each sample,
  // their offsets rising from 64 and inside the fragment.
  bool RleFitsHeader() {
    std::uint8_t header[64];
    if (pixels_.fragment_length < 64 || !Read(pixels_.first_fragment, header, 64)) return false;
    const std::uint32_t segments = U32(header);
    if (segments < 1 || segments > 15 || pixels_.bits_allocated < 8 ||
        segments != std::uint32_t(pixels_.samples) * std::uint32_t(pixels_.bits_allocated / 8)) {
      return false;
    }
    std::uint32_t previous = 63;
    for (std::uint32_t i = 0; i < segments; ++i) {
      const std::uint32_t offset = U32(header + 4 + 4 * i);
      if (offset <= previous || offset >= pixels_.fragment_length) return false;
      previous = offset;
    }
    return true;
  }

  // Elements up to the delimiter (FFFE,`delimiter`), which is consumed.
  bool Items(std::int64_t& at, std::int64_t end, bool explicit_vr, int depth, unsigned delimiter) {
    while (at + 8 <= end) {
      std::uint8_t h[4];
      if (!Read(at, h, 4)) return false;
      if (U16(h) == 0xfffe && U16(h + 2) == delimiter) {
        at += 8;
        return true;
      }
      if (!Element(at, end, explicit_vr, depth, false)) return false;
    }
    return false;
  }

  std::FILE* f_;
  std::int64_t size_;
  int elements_ = 0;
  std::string transfer_syntax_;  // from the file meta group
  PixelModule pixels_;
};

bool DicomStructureIsSound(const fs::path& path) {
  const file_checks::FileStream f = file_checks::OpenRegularStream(path);
  if (!f) return false;
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  return !ec && DicomWalk(f.get(), std::int64_t(size)).File();
}

// Scans `files`' headers. Files whose structure is not sound DICOM are
// left out (with the pre-checks on), and so are files GDCM cannot parse.
void ScanFiles(const std::vector<reader::DicomFile>& files, const reader::ReadOptions& options, Scan& scan) {
  itk_image::InitToolkits();
  scan.shown = options.shown;
  scan.files_seen = files.size();
  std::vector<std::string> sound;
  for (const reader::DicomFile& f : files) {
    scan.names[f.path] = f.name;
    if (!options.prechecks || DicomStructureIsSound(f.path)) sound.push_back(f.path);
  }
  for (const gdcm::Tag& t : {kSeriesUid, kSeriesDescription, kModality, kImagePosition, kImageOrientation, kRows,
                             kColumns, kSliceThickness, kPhotometric, kRescaleIntercept, kRescaleSlope}) {
    scan.scanner.AddTag(t);
  }
  if (!sound.empty() && !scan.scanner.Scan(sound)) {
    throw InputError(fmt::format("{}: could not scan the folder's files", scan.shown));
  }
  for (const std::string& f : sound) {
    if (scan.scanner.IsKey(f.c_str())) scan.dicom_files.push_back(f);
  }
  if (scan.dicom_files.empty()) {
    throw InputError(fmt::format("{}: no DICOM files found ({} files looked at)", scan.shown, scan.files_seen));
  }
}

std::string Value(const Scan& scan, const std::string& file, const gdcm::Tag& tag) {
  const char* v = scan.scanner.GetValue(file.c_str(), tag);
  std::string s = v ? v : "";
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  return s;
}

// Parses a backslash-separated decimal string such as "1\0\0\0\1\0"; empty
// when any item is not a finite number (NaN and infinities included).
std::vector<double> Numbers(const std::string& s) {
  std::vector<double> out;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, '\\');) {
    try {
      out.push_back(std::stod(item));
    } catch (const std::exception&) {
      return {};
    }
    if (!std::isfinite(out.back())) return {};
  }
  return out;
}

// Files grouped into series. Anonymised data may lack SeriesInstanceUID, so
// slices of another size or orientation count as a separate series too.
struct SeriesFiles {
  reader::Series info;
  std::vector<std::string> files;
};

std::vector<SeriesFiles> GroupSeries(const Scan& scan) {
  std::map<std::string, SeriesFiles> by_key;
  for (const std::string& f : scan.dicom_files) {
    const std::string uid = Value(scan, f, kSeriesUid);
    const std::string size = Value(scan, f, kColumns) + "x" + Value(scan, f, kRows);
    SeriesFiles& s = by_key[uid + "|" + size + "|" + Value(scan, f, kImageOrientation)];
    if (s.files.empty()) {
      s.info.set_uid(uid);
      s.info.set_description(Value(scan, f, kSeriesDescription));
      s.info.set_modality(Value(scan, f, kModality));
      s.info.set_size(size);
    }
    s.files.push_back(f);
    s.info.set_file_count(s.files.size());
  }
  std::vector<SeriesFiles> out;
  for (auto& [key, series] : by_key) out.push_back(std::move(series));
  std::stable_sort(out.begin(), out.end(), [](const SeriesFiles& a, const SeriesFiles& b) {
    return a.info.file_count() > b.info.file_count();
  });
  return out;
}

struct Slice {
  std::string file;
  double position[3];
  double along_normal;
};

// The checked, sorted geometry of one series.
struct SeriesGeometry {
  std::vector<Slice> slices;
  double row[3], col[3], normal[3];
  double slice_gap_mm = 1.0;
  // Above kMaxTiltDeg: the stack is sheared along its slices (a gantry tilt):
  // each slice is shifted in its own plane onto a regular grid, as Slicer does.
  double tilt_deg = 0;
};

double Dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

SeriesGeometry CheckGeometry(const Scan& scan, const std::vector<std::string>& files,
                             const std::string& where) {
  SeriesGeometry g;
  const std::vector<double> iop = Numbers(Value(scan, files[0], kImageOrientation));
  if (iop.size() != 6) {
    throw InputError(fmt::format("{}: {} has no usable ImageOrientationPatient", where, scan.Name(files[0])));
  }
  std::copy(iop.begin(), iop.begin() + 3, g.row);
  std::copy(iop.begin() + 3, iop.end(), g.col);
  g.normal[0] = g.row[1] * g.col[2] - g.row[2] * g.col[1];
  g.normal[1] = g.row[2] * g.col[0] - g.row[0] * g.col[2];
  g.normal[2] = g.row[0] * g.col[1] - g.row[1] * g.col[0];

  for (const std::string& f : files) {
    const std::vector<double> p = Numbers(Value(scan, f, kImagePosition));
    if (p.size() != 3) {
      throw InputError(fmt::format("{}: {} has no usable ImagePositionPatient", where, scan.Name(f)));
    }
    g.slices.push_back({f, {p[0], p[1], p[2]}, Dot3(p.data(), g.normal)});
  }
  std::sort(g.slices.begin(), g.slices.end(),
            [](const Slice& a, const Slice& b) { return a.along_normal < b.along_normal; });
  if (g.slices.size() < 2) {
    const std::vector<double> t = Numbers(Value(scan, files[0], kSliceThickness));
    g.slice_gap_mm = t.size() == 1 && t[0] > 0 ? t[0] : 1.0;
    return g;
  }

  std::vector<double> gaps;
  for (std::size_t i = 1; i < g.slices.size(); ++i) {
    const double gap = g.slices[i].along_normal - g.slices[i - 1].along_normal;
    if (gap < 1e-3) {
      throw InputError(fmt::format(
          "{}: {} and {} lie at the same position ({:.3f} mm along the normal): duplicate slices "
          "or several acquisitions in one series",
          where, scan.Name(g.slices[i - 1].file), scan.Name(g.slices[i].file), g.slices[i].along_normal));
    }
    gaps.push_back(gap);
  }
  std::vector<double> sorted = gaps;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  g.slice_gap_mm = sorted[sorted.size() / 2];
  for (std::size_t i = 0; i < gaps.size(); ++i) {
    if (std::abs(gaps[i] - g.slice_gap_mm) > kGapTolerance * g.slice_gap_mm) {
      throw InputError(fmt::format(
          "{}: uneven slice spacing: {:.3f} mm between {} and {} where the series' gap is {:.3f} "
          "mm (missing slices?); cinevol loads evenly spaced series only",
          where, gaps[i], scan.Name(g.slices[i].file), scan.Name(g.slices[i + 1].file), g.slice_gap_mm));
    }
  }
  // Gantry tilt: the stack's direction leaves the slice normal.
  const Slice& first = g.slices.front();
  const Slice& last = g.slices.back();
  double step[3];
  for (int a = 0; a < 3; ++a) step[a] = last.position[a] - first.position[a];
  const double cos_tilt = Dot3(step, g.normal) / std::sqrt(Dot3(step, step));
  g.tilt_deg = std::acos(std::min(1.0, std::abs(cos_tilt))) * 180.0 / M_PI;
  return g;
}

std::string Describe(const reader::Series& s) {
  return fmt::format("{} '{}' ({}, {} pixels, {} files)", s.uid().empty() ? "(no SeriesInstanceUID)" : s.uid(),
                     s.description(), s.modality(), s.size(), s.file_count());
}

// The largest series, or the largest with `requested` as its UID.
SeriesFiles ChooseSeries(std::vector<SeriesFiles> all, const std::string& requested, const std::string& where) {
  std::size_t chosen = 0;
  if (!requested.empty()) {
    chosen = all.size();
    for (std::size_t i = 0; i < all.size() && chosen == all.size(); ++i) {
      if (all[i].info.uid() == requested) chosen = i;
    }
    if (chosen == all.size()) {
      std::string known;
      for (const auto& s : all) known += "\n  " + Describe(s.info);
      throw InputError(fmt::format("{}: no series {}; the folder holds:{}", where, requested, known));
    }
  }
  return std::move(all[chosen]);
}

// Grey-scale slices only: GDCM decodes colour models (YBR_*, RGB, ARGB,
// PALETTE COLOR) into several components, and aborts or crashes on some that
// disagree with their codec (a JPEG 2000 slice marked YBR_RCT, an
// uncompressed one marked ARGB).
void CheckGreyScale(const Scan& scan, const std::vector<std::string>& files, const std::string& where) {
  for (const std::string& f : files) {
    const std::string pi = Value(scan, f, kPhotometric);
    if (pi != "MONOCHROME1" && pi != "MONOCHROME2" && !pi.empty()) {
      throw InputError(fmt::format("{}: {} has Photometric Interpretation '{}'; cinevol reads grey-scale series "
                                   "(MONOCHROME1 or MONOCHROME2)",
                                   where, scan.Name(f), pi.substr(0, 32)));
    }
  }
}

// Whether every file of the series has the same rescale slope and intercept:
// else each slice is rescaled on its own, into float32.
bool SameRescale(const Scan& scan, const std::vector<std::string>& files) {
  for (const std::string& f : files) {
    if (Value(scan, f, kRescaleSlope) != Value(scan, files[0], kRescaleSlope) ||
        Value(scan, f, kRescaleIntercept) != Value(scan, files[0], kRescaleIntercept)) {
      return false;
    }
  }
  return true;
}

// Converts `n` values of ITK component `from` at `in` to float32 at `out`.
void ToFloat(itk::IOComponentEnum from, const void* in, float* out, std::size_t n) {
  using C = itk::IOComponentEnum;
  auto copy = [&](auto* typed) {
    for (std::size_t i = 0; i < n; ++i) out[i] = float(typed[i]);
  };
  switch (from) {
    case C::UCHAR: copy(static_cast<const std::uint8_t*>(in)); break;
    case C::CHAR: copy(static_cast<const std::int8_t*>(in)); break;
    case C::USHORT: copy(static_cast<const std::uint16_t*>(in)); break;
    case C::SHORT: copy(static_cast<const std::int16_t*>(in)); break;
    case C::UINT: copy(static_cast<const std::uint32_t*>(in)); break;
    case C::INT: copy(static_cast<const std::int32_t*>(in)); break;
    case C::FLOAT: copy(static_cast<const float*>(in)); break;
    case C::DOUBLE: copy(static_cast<const double*>(in)); break;
    default: throw InputError("a slice of a voxel type cinevol does not read");
  }
}

// One series, its slices sorted and its header known; the pixels are
// decoded slice by slice (GDCM: JPEG 2000 and other compressed transfer
// syntaxes included; rescale slope and intercept applied).
class DicomSeriesRead final : public reader::VolumeRead {
 public:
  DicomSeriesRead(const Scan& scan, const SeriesFiles& series, const SeriesGeometry& g, std::uint64_t max_voxels)
      : where_(scan.shown), series_(series.info) {
    for (const Slice& s : g.slices) files_.push_back(s.file);
    auto io = itk::GDCMImageIO::New();
    try {
      // Header sizes are checked before decoding: absurd rows/columns never allocate.
      io->SetFileName(files_[0]);
      io->ReadImageInformation();
    } catch (const itk::ExceptionObject& e) {
      throw Failed(e);
    }
    if (io->GetNumberOfComponents() != 1) {
      throw InputError(fmt::format("{}: series {} holds pixels of {} components; cinevol reads grey-scale series",
                                   where_, Describe(series_), io->GetNumberOfComponents()));
    }
    const std::uint64_t frames = io->GetNumberOfDimensions() > 2 ? std::max<std::uint64_t>(1, io->GetDimensions(2)) : 1;
    if (frames > 1 && files_.size() > 1) {
      throw InputError(fmt::format("{}: series {} has multi-frame files; cinevol reads one such file, or single-frame "
                                   "slices", where_, Describe(series_)));
    }
    const std::array<int, 3> dims{int(std::min<std::uint64_t>(io->GetDimensions(0), 1u << 30)),
                                  int(std::min<std::uint64_t>(io->GetDimensions(1), 1u << 30)),
                                  int(std::min<std::uint64_t>(files_.size() * frames, 1u << 30))};
    CheckVolumeGeometry({dims[0], dims[1], dims[2]},
                        {float(io->GetSpacing(0)), float(io->GetSpacing(1)), float(g.slice_gap_mm)}, where_);
    const std::uint64_t voxels = std::uint64_t(dims[0]) * std::uint64_t(dims[1]) * std::uint64_t(dims[2]);
    if (voxels > max_voxels) {
      throw InputError(fmt::format("{}: {}x{}x{} = {} voxels exceeds this server's limit of {} voxels", where_,
                                   dims[0], dims[1], dims[2], voxels, max_voxels));
    }
    // Geometry from the sorted positions, not from the first two files.
    std::array<double, 9> direction;
    for (int r = 0; r < 3; ++r) {
      direction[3 * r + 0] = g.row[r];
      direction[3 * r + 1] = g.col[r];
      direction[3 * r + 2] = g.normal[r];
    }
    const Slice& first = g.slices.front();
    itk_image::SetGeometry(header_, dims, {io->GetSpacing(0), io->GetSpacing(1), g.slice_gap_mm},
                           {first.position[0], first.position[1], first.position[2]}, direction);
    type_ = io->GetComponentType();
    rescaled_alike_ = SameRescale(scan, files_);
    header_.set_voxel_type(rescaled_alike_ ? itk_image::VoxelTypeOf(type_) : "float32");
    if (header_.voxel_type().empty()) {
      throw InputError(fmt::format("{}: series {} holds voxels of type {}, which cinevol does not read", where_,
                                   Describe(series_), itk_image::ComponentName(type_)));
    }
    header_.set_modality(Value(scan, files_[0], kModality));
    header_.set_value_unit(header_.modality() == "CT" ? "HU" : "");
    std::string original = itk_image::ComponentName(io->GetInternalComponentType());
    if (io->GetRescaleSlope() != 1.0 || io->GetRescaleIntercept() != 0.0) {
      original += fmt::format(" (rescale slope {:g}, intercept {:g})", io->GetRescaleSlope(), io->GetRescaleIntercept());
    }
    header_.set_original_type(original);
    slice_voxels_ = std::size_t(dims[0]) * std::size_t(dims[1]) * std::size_t(frames);
    if (g.tilt_deg > kMaxTiltDeg) Shear(g, io->GetSpacing(0), io->GetSpacing(1), dims);
  }

  void Read(void* memory, std::size_t bytes) override {
    const std::size_t voxel_bytes = BytesPerVoxel(*VoxelTypeNamed(header_.voxel_type()));
    if (bytes != slice_voxels_ * voxel_bytes * files_.size()) {
      throw InputError(fmt::format("{}: {} bytes of memory for the series' voxels", where_, bytes));
    }
    std::vector<char> scratch;
    for (std::size_t k = 0; k < files_.size(); ++k) {
      auto io = itk::GDCMImageIO::New();
      char* out = static_cast<char*>(memory) + k * slice_voxels_ * voxel_bytes;
      try {
        io->SetFileName(files_[k]);
        io->ReadImageInformation();
        const std::size_t n = io->GetImageSizeInPixels();
        if (io->GetNumberOfComponents() != 1 || n != slice_voxels_ ||
            (rescaled_alike_ && io->GetComponentType() != type_)) {
          throw InputError(fmt::format("{}: a slice of series {} differs from the first in size or voxel type",
                                       where_, Describe(series_)));
        }
        itk::ImageIORegion region(io->GetNumberOfDimensions());
        for (unsigned a = 0; a < io->GetNumberOfDimensions(); ++a) {
          region.SetIndex(a, 0);
          region.SetSize(a, io->GetDimensions(a));
        }
        io->SetIORegion(region);
        if (rescaled_alike_ && shifts_.empty()) {
          io->Read(out);
        } else {
          scratch.resize(io->GetImageSizeInBytes());
          io->Read(scratch.data());
          ToFloat(io->GetComponentType(), scratch.data(), reinterpret_cast<float*>(out), n);
          if (!shifts_.empty()) ShiftSlice(reinterpret_cast<float*>(out), shifts_[k], io->GetComponentType());
        }
      } catch (const itk::ExceptionObject& e) {
        throw Failed(e);
      }
    }
  }

 private:
  // A gantry-tilted series: each slice's offset in its own plane (voxels along
  // row and column) from where a regular grid puts it; read as float32.
  void Shear(const SeriesGeometry& g, double row_mm, double col_mm, const std::array<int, 3>& dims) {
    const Slice& first = g.slices.front();
    for (std::size_t k = 0; k < g.slices.size(); ++k) {
      double d[3];
      for (int a = 0; a < 3; ++a) d[a] = g.slices[k].position[a] - first.position[a];
      shifts_.push_back({Dot3(d, g.row) / row_mm, Dot3(d, g.col) / col_mm});
    }
    width_ = dims[0];
    height_ = dims[1];
    header_.set_voxel_type("float32");
    header_.add_notes(fmt::format("resampled from a gantry tilt of {:.1f} degrees onto a regular grid: each slice "
                                  "shifted in its own plane",
                                  g.tilt_deg));
  }

  // Moves a slice by its offset: the regular grid's voxel (i, j) is the
  // slice's (i - dx, j - dy), interpolated bilinearly; what falls outside the
  // slice takes its lowest value (air). Integer data are rounded again.
  void ShiftSlice(float* slice, std::array<double, 2> shift, itk::IOComponentEnum type) const {
    const std::vector<float> in(slice, slice + std::size_t(width_) * height_);
    const float fill = *std::min_element(in.begin(), in.end());
    const bool integral = type != itk::IOComponentEnum::FLOAT && type != itk::IOComponentEnum::DOUBLE;
    for (int j = 0; j < height_; ++j) {
      for (int i = 0; i < width_; ++i) {
        const double x = i - shift[0], y = j - shift[1];
        const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
        const double fx = x - x0, fy = y - y0;
        auto at = [&](int xi, int yi) {
          return xi < 0 || yi < 0 || xi >= width_ || yi >= height_ ? double(fill)
                                                                    : double(in[std::size_t(yi) * width_ + xi]);
        };
        const double v = (at(x0, y0) * (1 - fx) + at(x0 + 1, y0) * fx) * (1 - fy) +
                         (at(x0, y0 + 1) * (1 - fx) + at(x0 + 1, y0 + 1) * fx) * fy;
        slice[std::size_t(j) * width_ + i] = float(integral ? std::nearbyint(v) : v);
      }
    }
  }

  InputError Failed(const itk::ExceptionObject& e) const {
    return InputError(fmt::format("{}: cannot decode series {}: {}", where_, Describe(series_),
                                  itk_image::ItkMessage(e, {}, where_)));
  }

  std::string where_;
  reader::Series series_;
  std::vector<std::string> files_;  // sorted along the normal
  itk::IOComponentEnum type_ = itk::IOComponentEnum::UNKNOWNCOMPONENTTYPE;
  bool rescaled_alike_ = true;
  std::size_t slice_voxels_ = 0;
  std::vector<std::array<double, 2>> shifts_;  // per slice, for a tilted series; empty otherwise
  int width_ = 0, height_ = 0;
};

}  // namespace

namespace reader {

SeriesList ListDicomSeries(const std::vector<DicomFile>& files, const ReadOptions& options) {
  Scan scan;
  ScanFiles(files, options, scan);
  SeriesList out;
  for (const SeriesFiles& s : GroupSeries(scan)) *out.add_series() = s.info;
  return out;
}

std::unique_ptr<VolumeRead> OpenDicomSeries(const std::vector<DicomFile>& files, const std::string& series_uid,
                                            const ReadOptions& options) {
  Scan scan;
  ScanFiles(files, options, scan);
  const SeriesFiles series = ChooseSeries(GroupSeries(scan), series_uid, scan.shown);
  const SeriesGeometry g = CheckGeometry(scan, series.files, scan.shown);
  CheckGreyScale(scan, series.files, scan.shown);
  return std::make_unique<DicomSeriesRead>(scan, series, g, options.max_voxels);
}

}  // namespace reader
}  // namespace cinevol
