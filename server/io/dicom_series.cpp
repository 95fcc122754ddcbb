// DICOM series from a folder: GDCM scans the headers, cinevol groups, sorts
// and checks the slices, ITK/GDCM decodes the pixels (JPEG 2000 and other
// compressed transfer syntaxes included) and applies rescale slope/intercept.
#include <gdcmScanner.h>
#include <itkGDCMImageIO.h>
#include <itkImageSeriesReader.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "core/error.h"
#include "io/file_checks.h"
#include "io/itk_image.h"
#include "io/volume_loader.h"

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

// A folder with more files than this is not one patient's series.
constexpr std::size_t kMaxFolderFiles = 100000;

// Slices whose positions along the normal differ by more than this fraction
// of the typical gap count as unevenly spaced.
constexpr double kGapTolerance = 0.01;
// Slice stacks sheared by more than this (degrees) count as gantry tilt.
constexpr double kMaxTiltDeg = 0.1;

struct Scan {
  gdcm::Scanner scanner;
  std::vector<std::string> dicom_files;  // files that parsed as DICOM
  std::size_t files_seen = 0;
  std::string folder;  // as given
  std::string shown;   // what messages call the folder

  // What messages call a file in the folder: its path under `shown`.
  std::string Name(const std::string& file) const {
    return file.rfind(folder, 0) == 0 ? shown + file.substr(folder.size()) : file;
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
    }
    if (at == size_) return true;
    // The data set: explicit VR when the bytes after the first tag read as a
    // VR (GDCM guesses the same way when the meta group is absent or wrong).
    std::uint8_t h[6];
    const bool explicit_vr = at + 6 <= size_ && Read(at, h, 6) && IsVr(h + 4);
    while (at < size_) {
      if (!Element(at, size_, explicit_vr, 0, false)) return false;
    }
    return true;
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
    if (length == 0xffffffffu) {
      // Encapsulated pixel data: fragments, each an item of plain bytes.
      const bool fragments = (group == 0x7fe0 && element == 0x0010) ||
                             (explicit_vr && !sequence && std::memcmp(h + 4, "UN", 2) != 0);
      if (fragments) return Fragments(at, end);
      // A sequence: items of elements (implicit VR inside an undefined-length UN).
      const bool inner_explicit = explicit_vr && std::memcmp(h + 4, "UN", 2) != 0;
      return Items(at, end, inner_explicit, depth + 1, 0xe0dd);
    }
    if (length > std::uint64_t(end - at)) return false;
    // GDCM asserts that Samples per Pixel is at most 4 (an abort, found by
    // fuzz_volume): 1 (grey) to 4 only, in any image, icons included.
    if (group == 0x0028 && element == 0x0002 && !meta) {
      std::uint8_t v[2];
      if (length < 2 || !Read(at, v, 2) || U16(v) < 1 || U16(v) > 4) return false;
    }
    at += length;
    return true;
  }

  // Items of plain bytes up to the sequence delimiter, which is consumed.
  bool Fragments(std::int64_t& at, std::int64_t end) {
    while (at + 8 <= end) {
      std::uint8_t h[8];
      if (!Read(at, h, 8) || U16(h) != 0xfffe || ++elements_ > 200000) return false;
      at += 8;
      if (U16(h + 2) == 0xe0dd) return true;
      const std::uint32_t length = U32(h + 4);
      if (U16(h + 2) != 0xe000 || length > std::uint64_t(end - at)) return false;
      at += length;
    }
    return false;
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
};

bool DicomStructureIsSound(const fs::path& path) {
  const file_checks::FileStream f = file_checks::OpenRegularStream(path);
  if (!f) return false;
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  return !ec && DicomWalk(f.get(), std::int64_t(size)).File();
}

// The regular files under `folder` (subfolders included, symlinked folders
// not followed) that the policy lets a load read: FIFOs, sockets and devices
// are skipped without being opened; kInsideRoots keeps files inside the
// roots, kNone files inside the folder itself. Files whose structure is not
// sound DICOM are left out too; `looked_at` counts every file examined.
std::vector<std::string> FolderFiles(const fs::path& folder, const LoadPolicy& policy, const std::string& shown,
                                     std::size_t& looked_at) {
  using R = LoadPolicy::References;
  std::error_code ec;
  const std::vector<fs::path> allowed = policy.references == R::kNone ? std::vector<fs::path>{fs::canonical(folder, ec)}
                                                                      : policy.roots;
  std::vector<std::string> files;
  for (fs::recursive_directory_iterator it(folder, fs::directory_options::skip_permission_denied, ec), end;
       !ec && it != end; it.increment(ec)) {
    if (it->is_directory(ec) || !file_checks::IsRegularFile(it->path())) continue;
    if (policy.references != R::kAnywhere && !file_checks::IsInside(fs::canonical(it->path(), ec), allowed)) continue;
    // Counted before the structure check, which reads each file: the limit bounds that work too.
    if (looked_at == kMaxFolderFiles) {
      throw InputError(fmt::format("{}: more than {} files in the folder", shown, kMaxFolderFiles));
    }
    ++looked_at;
    if (DicomStructureIsSound(it->path())) files.push_back(it->path().string());
  }
  if (ec) throw InputError(fmt::format("{}: cannot list the folder", shown));
  return files;
}

void ScanFolder(const fs::path& folder, const LoadPolicy& policy, Scan& scan) {
  itk_image::InitToolkits();
  scan.folder = folder.string();
  scan.shown = file_checks::Shown(folder, policy);
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    throw InputError(fmt::format("{}: not a folder", scan.shown));
  }
  file_checks::RequireInsideRoots(folder, policy, scan.shown);
  const std::vector<std::string> files = FolderFiles(folder, policy, scan.shown, scan.files_seen);
  for (const gdcm::Tag& t : {kSeriesUid, kSeriesDescription, kModality, kImagePosition,
                             kImageOrientation, kRows, kColumns, kSliceThickness}) {
    scan.scanner.AddTag(t);
  }
  if (!files.empty() && !scan.scanner.Scan(files)) {
    throw InputError(fmt::format("{}: could not scan the folder's files", scan.shown));
  }
  for (const std::string& f : files) {
    if (scan.scanner.IsKey(f.c_str())) scan.dicom_files.push_back(f);
  }
  if (scan.dicom_files.empty()) {
    throw InputError(fmt::format("{}: no DICOM files found ({} files looked at)", scan.shown,
                                 scan.files_seen));
  }
}

std::string Value(const Scan& scan, const std::string& file, const gdcm::Tag& tag) {
  const char* v = scan.scanner.GetValue(file.c_str(), tag);
  std::string s = v ? v : "";
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  return s;
}

// Parses a backslash-separated decimal string such as "1\0\0\0\1\0".
std::vector<double> Numbers(const std::string& s) {
  std::vector<double> out;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, '\\');) {
    try {
      out.push_back(std::stod(item));
    } catch (const std::exception&) {
      return {};
    }
  }
  return out;
}

// Files grouped into series. Anonymised data may lack SeriesInstanceUID, so
// slices of another size or orientation count as a separate series too.
struct Series {
  DicomSeriesInfo info;
  std::vector<std::string> files;
};

std::vector<Series> GroupSeries(const Scan& scan) {
  std::map<std::string, Series> by_key;
  for (const std::string& f : scan.dicom_files) {
    const std::string uid = Value(scan, f, kSeriesUid);
    const std::string size = Value(scan, f, kColumns) + "x" + Value(scan, f, kRows);
    Series& s = by_key[uid + "|" + size + "|" + Value(scan, f, kImageOrientation)];
    if (s.files.empty()) {
      s.info = {uid, Value(scan, f, kSeriesDescription), Value(scan, f, kModality), size, 0};
    }
    s.files.push_back(f);
    s.info.file_count = s.files.size();
  }
  std::vector<Series> out;
  for (auto& [key, series] : by_key) out.push_back(std::move(series));
  std::stable_sort(out.begin(), out.end(), [](const Series& a, const Series& b) {
    return a.info.file_count > b.info.file_count;
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
  const double tilt_deg = std::acos(std::min(1.0, std::abs(cos_tilt))) * 180.0 / M_PI;
  if (tilt_deg > kMaxTiltDeg) {
    throw InputError(fmt::format(
        "{}: gantry tilt of {:.2f} degrees (slices are sheared along the stack); cinevol does "
        "not resample tilted series",
        where, tilt_deg));
  }
  return g;
}

std::string Describe(const DicomSeriesInfo& s) {
  return fmt::format("{} '{}' ({}, {} pixels, {} files)", s.uid.empty() ? "(no SeriesInstanceUID)" : s.uid,
                     s.description, s.modality, s.size, s.file_count);
}

// The largest series, or the largest with `requested` as its UID.
Series ChooseSeries(std::vector<Series> all, const std::string& requested, const std::string& where) {
  std::size_t chosen = 0;
  if (!requested.empty()) {
    chosen = all.size();
    for (std::size_t i = 0; i < all.size() && chosen == all.size(); ++i) {
      if (all[i].info.uid == requested) chosen = i;
    }
    if (chosen == all.size()) {
      std::string known;
      for (const auto& s : all) known += "\n  " + Describe(s.info);
      throw InputError(fmt::format("{}: no series {}; the folder holds:{}", where, requested, known));
    }
  }
  for (std::size_t i = 0; i < all.size(); ++i) {
    // Debug level: folder paths and series descriptions are not for the info log.
    if (i != chosen) spdlog::debug("{}: also holds series {}; not loaded", where, Describe(all[i].info));
  }
  return std::move(all[chosen]);
}

}  // namespace

std::vector<DicomSeriesInfo> ListDicomSeries(const fs::path& folder) {
  Scan scan;
  ScanFolder(folder, {}, scan);
  std::vector<DicomSeriesInfo> out;
  for (const Series& s : GroupSeries(scan)) out.push_back(s.info);
  return out;
}

Volume LoadDicomSeries(const fs::path& folder, const std::string& series_uid, const LoadPolicy& policy) {
  Scan scan;
  ScanFolder(folder, policy, scan);
  const std::string where = scan.shown;
  const Series series = ChooseSeries(GroupSeries(scan), series_uid, where);
  const std::vector<std::string>& files = series.files;
  const SeriesGeometry g = CheckGeometry(scan, files, where);

  auto io = itk::GDCMImageIO::New();
  auto reader = itk::ImageSeriesReader<itk_image::FloatImage>::New();
  reader->SetImageIO(io);
  std::vector<std::string> sorted;
  for (const Slice& s : g.slices) sorted.push_back(s.file);
  reader->SetFileNames(sorted);
  try {
    // Header sizes are checked before decoding: absurd rows/columns never allocate.
    io->SetFileName(sorted[0]);
    io->ReadImageInformation();
    CheckVolumeGeometry({int(io->GetDimensions(0)), int(io->GetDimensions(1)), int(sorted.size())},
                        {float(io->GetSpacing(0)), float(io->GetSpacing(1)), float(g.slice_gap_mm)},
                        where);
    const std::uint64_t frames = io->GetNumberOfDimensions() > 2 ? std::max<std::uint64_t>(1, io->GetDimensions(2)) : 1;
    const std::uint64_t voxels = std::uint64_t(io->GetDimensions(0)) * io->GetDimensions(1) * sorted.size() * frames;
    if (voxels > policy.max_voxels) {
      throw InputError(fmt::format("{}: {}x{}x{} = {} voxels exceeds this server's limit of {} voxels", where,
                                   io->GetDimensions(0), io->GetDimensions(1), sorted.size() * frames, voxels,
                                   policy.max_voxels));
    }
    reader->Update();
  } catch (const itk::ExceptionObject& e) {
    throw InputError(fmt::format("{}: cannot decode series {}: {}", where, Describe(series.info),
                                 itk_image::ItkMessage(e, {folder}, where)));
  }
  auto* image = reader->GetOutput();
  // Geometry from the sorted positions, not from the first two files ITK saw.
  auto spacing = image->GetSpacing();
  spacing[2] = g.slice_gap_mm;
  image->SetSpacing(spacing);
  itk_image::FloatImage::PointType origin;
  itk_image::FloatImage::DirectionType direction;
  for (int r = 0; r < 3; ++r) {
    origin[r] = g.slices.front().position[r];
    direction[r][0] = g.row[r];
    direction[r][1] = g.col[r];
    direction[r][2] = g.normal[r];
  }
  image->SetOrigin(origin);
  image->SetDirection(direction);

  VolumeMetadata meta;
  meta.source = where;
  meta.modality = Value(scan, files[0], kModality);
  meta.value_unit = meta.modality == "CT" ? "HU" : "";
  meta.original_type = itk_image::ComponentName(io->GetInternalComponentType());
  if (io->GetRescaleSlope() != 1.0 || io->GetRescaleIntercept() != 0.0) {
    meta.original_type += fmt::format(" (rescale slope {:g}, intercept {:g})", io->GetRescaleSlope(),
                                      io->GetRescaleIntercept());
  }
  return itk_image::ToVolume(image, std::move(meta));
}

}  // namespace cinevol
