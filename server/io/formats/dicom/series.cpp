// DICOM series: GDCM scans the headers, cinevol groups, sorts and checks them.
#include "io/formats/dicom/series.h"

#include <fmt/format.h>
#include <gdcmReader.h>
#include <gdcmScanner.h>
#include <gdcmSequenceOfItems.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <sstream>

#include "core/error.h"
#include "core/volume.h"
#include "io/formats/dicom/checks.h"
#include "io/formats/dicom/frames.h"

namespace fs = std::filesystem;

namespace cinevol::formats::dicom {
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
const gdcm::Tag kWindowCenter(0x0028, 0x1050);
const gdcm::Tag kWindowWidth(0x0028, 0x1051);
const gdcm::Tag kPatientName(0x0010, 0x0010);
const gdcm::Tag kPatientId(0x0010, 0x0020);
const gdcm::Tag kStudyDate(0x0008, 0x0020);
const gdcm::Tag kStudyDescription(0x0008, 0x1030);
const gdcm::Tag kFrameOfReference(0x0020, 0x0052);
const gdcm::Tag kTemporalPosition(0x0020, 0x0100);
const gdcm::Tag kTriggerTime(0x0018, 0x1060);
const gdcm::Tag kInstanceNumber(0x0020, 0x0013);
// A PET's attributes for SUVbw (reader.proto's PetDose).
const gdcm::Tag kUnits(0x0054, 0x1001);
const gdcm::Tag kDecayCorrection(0x0054, 0x1102);
const gdcm::Tag kCorrectedImage(0x0028, 0x0051);
const gdcm::Tag kPatientWeight(0x0010, 0x1030);
const gdcm::Tag kSeriesDate(0x0008, 0x0021);
const gdcm::Tag kSeriesTime(0x0008, 0x0031);
const gdcm::Tag kAcquisitionDate(0x0008, 0x0022);
const gdcm::Tag kAcquisitionTime(0x0008, 0x0032);
const gdcm::Tag kPetTags[] = {kUnits,      kDecayCorrection, kCorrectedImage,  kPatientWeight,
                              kSeriesDate, kSeriesTime,      kAcquisitionDate, kAcquisitionTime};
const gdcm::Tag kRadiopharmaceuticalInformation(0x0054, 0x0016);  // a sequence; its first item holds:
const gdcm::Tag kRadiopharmaceuticalStartTime(0x0018, 0x1072);
const gdcm::Tag kRadionuclideTotalDose(0x0018, 0x1074);
const gdcm::Tag kRadionuclideHalfLife(0x0018, 0x1075);
const gdcm::Tag kRadiopharmaceuticalStartDateTime(0x0018, 0x1078);

const gdcm::Tag kNumberOfFrames(0x0028, 0x0008);

// What orders a position's slices in time (Slice::time_keys), the first every
// slice of the series has; the second is a trigger time in ms.
struct TimeKey {
  const char* name;
  const char* unit;
};
using TimeKeys = std::array<TimeKey, 3>;
const TimeKeys kFileTimeKeys{
    {{"Temporal Position Identifier", ""}, {"Trigger Time", " ms"}, {"Instance Number", ""}}};
const TimeKeys kFrameTimeKeys{
    {{"Temporal Position Index", ""}, {"Nominal Cardiac Trigger Delay Time", " ms"}, {"frame number", ""}}};

// Slices whose positions along the normal differ by more than this fraction
// of the typical gap count as unevenly spaced.
constexpr double kGapTolerance = 0.01;

struct Scan {
  gdcm::Scanner scanner;
  std::vector<std::string> dicom_files;  // paths of files that parsed as DICOM
  std::size_t files_seen = 0;
  std::map<std::string, std::string> names;  // path -> the file's path under the folder
  std::string shown;                         // what messages call the folder
  std::string first_problem;                 // "; FILE is not DICOM ...: why", for a refusal

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

  // A slice: its file, and its frame where it is one of a multi-frame file's.
  std::string Name(const Slice& slice) const {
    return slice.frame < 0 ? Name(slice.file) : fmt::format("{} frame {}", Name(slice.file), slice.frame + 1);
  }
};

// Scans `files`' headers. Files whose structure is not sound DICOM are
// left out (with the pre-checks on), and so are files GDCM cannot parse; where
// none is left, the refusal names the first unsound file and its problem.
void ScanFiles(const std::vector<reader::DicomFile>& files, const reader::ReadOptions& options, Scan& scan) {
  scan.shown = options.shown;
  scan.files_seen = files.size();
  std::vector<std::string> sound;
  for (const reader::DicomFile& f : files) {
    scan.names[f.path] = f.name;
    const std::string problem = options.prechecks ? StructureProblem(f.path) : std::string();
    if (problem.empty()) {
      sound.push_back(f.path);
    } else if (scan.first_problem.empty()) {
      scan.first_problem = fmt::format("; {} is not DICOM that cinevol reads: {}", scan.Name(f.path), problem);
    }
  }
  for (const gdcm::Tag& t : {kSeriesUid, kSeriesDescription, kModality, kImagePosition, kImageOrientation, kRows,
                             kColumns, kSliceThickness, kPhotometric, kRescaleIntercept, kRescaleSlope, kWindowCenter,
                             kWindowWidth, kPatientName, kPatientId, kStudyDate, kStudyDescription,
                             kFrameOfReference, kTemporalPosition, kTriggerTime, kInstanceNumber,
                             kNumberOfFrames}) {
    scan.scanner.AddTag(t);
  }
  for (const gdcm::Tag& t : kPetTags) scan.scanner.AddTag(t);
  if (!sound.empty() && !scan.scanner.Scan(sound)) {
    throw InputError(fmt::format("{}: could not scan the folder's files", scan.shown));
  }
  for (const std::string& f : sound) {
    if (scan.scanner.IsKey(f.c_str())) scan.dicom_files.push_back(f);
  }
  if (scan.dicom_files.empty()) {
    throw InputError(
        fmt::format("{}: no DICOM files found{} ({} files looked at{})", scan.shown,
                    scan.first_problem.empty() ? "" : " that cinevol reads", scan.files_seen, scan.first_problem));
  }
}

std::string Value(const Scan& scan, const std::string& file, const gdcm::Tag& tag) {
  const char* v = scan.scanner.GetValue(file.c_str(), tag);
  std::string s = v ? v : "";
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  return s;
}

// The file's value of `tag` where it holds one number; else nothing.
std::optional<double> Number(const Scan& scan, const std::string& file, const gdcm::Tag& tag) {
  const std::vector<double> v = Numbers(Value(scan, file, tag));
  if (v.size() != 1) return std::nullopt;
  return v[0];
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

}  // namespace

std::size_t SeriesGeometry::GridSlices() const {
  if (!uneven) return slices.size();
  const double span = slices.back().along_normal - slices.front().along_normal;
  return std::size_t(std::floor(span / slice_gap_mm + 1e-6)) + 1;
}

namespace {

// Slices nearer than this along the normal (mm) lie at one position.
constexpr double kSamePositionMm = 1e-3;

// A series' files at one position along the normal.
using Position = std::vector<Slice>;

// `slices`, sorted along the normal, grouped by position.
std::vector<Position> GroupPositions(const std::vector<Slice>& slices) {
  std::vector<Position> out;
  for (const Slice& s : slices) {
    if (out.empty() || s.along_normal - out.back().back().along_normal >= kSamePositionMm) out.emplace_back();
    out.back().push_back(s);
  }
  return out;
}

// A time series (several slices at a position): each position's slices
// ordered in time by the first of `keys` every slice has; refused where two
// slices of a position have the same time (or nothing orders them), where
// positions hold different counts, or where there are more than kMaxPhases
// phases. Sets `out`'s phase order and times.
void OrderPhases(const Scan& scan, const TimeKeys& keys, std::vector<Position>& positions, SortedSeries& out) {
  const std::string& where = out.shown;
  std::optional<std::size_t> key;
  for (std::size_t k = 0; k < keys.size() && !key; ++k) {
    bool every = true;
    for (const Position& p : positions) {
      for (const Slice& s : p) every = every && s.time_keys[k].has_value();
    }
    if (every) key = k;
  }
  const auto time = [&](const Slice& s) { return *s.time_keys[*key]; };
  // Two slices of one position at one time are duplicates, whatever the counts.
  for (Position& p : positions) {
    if (key) std::stable_sort(p.begin(), p.end(), [&](const Slice& a, const Slice& b) { return time(a) < time(b); });
    for (std::size_t i = 1; i < p.size(); ++i) {
      if (key && time(p[i]) != time(p[i - 1])) continue;
      throw InputError(fmt::format(
          "{}: {} and {} lie at the same position ({:.3f} mm along the normal): duplicate slices or several "
          "acquisitions in one series ({})",
          where, scan.Name(p[i - 1]), scan.Name(p[i]), p[i].along_normal,
          key ? fmt::format("both with {} {:g}{}", keys[*key].name, time(p[i]), keys[*key].unit)
              : fmt::format("no {}, {} or {} orders them in time", keys[0].name, keys[1].name, keys[2].name)));
    }
  }
  // The most common count is the series' phases; a position holding another
  // is named.
  std::map<std::size_t, std::size_t> positions_holding;  // slices -> positions holding that many
  for (const Position& p : positions) ++positions_holding[p.size()];
  const std::size_t phases =
      std::max_element(positions_holding.begin(), positions_holding.end(),
                       [](const auto& a, const auto& b) { return a.second < b.second; })->first;
  for (const Position& p : positions) {
    if (p.size() == phases) continue;
    throw InputError(fmt::format("{}: positions hold {} and {} slices: not one phase a position ({} at {:.3f} mm "
                                 "along the normal, {} among them; a phase missing, or another acquisition?)",
                                 where, phases, p.size(), p.size(), p.front().along_normal, scan.Name(p.front())));
  }
  if (phases > std::size_t(kMaxPhases)) {
    throw InputError(fmt::format("{}: a time series of {} phases ({} slices at each of {} position{}); cinevol "
                                 "reads 1 to {}",
                                 where, phases, phases, positions.size(), positions.size() == 1 ? "" : "s",
                                 kMaxPhases));
  }
  out.phase_order = keys[*key].name;
  // Each phase's time: the mean of its slices' trigger times, where every
  // slice has one and the means rise phase by phase.
  std::vector<double> seconds(phases, 0.0);
  for (const Position& p : positions) {
    for (std::size_t k = 0; k < phases; ++k) {
      const std::optional<double> ms = p[k].time_keys[1];
      if (!ms) return;
      seconds[k] += *ms / 1000.0 / double(positions.size());
    }
  }
  for (std::size_t k = 1; k < phases; ++k) {
    if (!(seconds[k] > seconds[k - 1])) return;
  }
  out.phase_seconds = std::move(seconds);
}

// The slices' plane from an Image Orientation (Patient): row, column, normal.
void SetPlane(const double* iop, SeriesGeometry& g) {
  std::copy(iop, iop + 3, g.row);
  std::copy(iop + 3, iop + 6, g.col);
  g.normal[0] = g.row[1] * g.col[2] - g.row[2] * g.col[1];
  g.normal[1] = g.row[2] * g.col[0] - g.row[0] * g.col[2];
  g.normal[2] = g.row[0] * g.col[1] - g.row[1] * g.col[0];
}

// Each file's one image as a slice, the plane the first file's.
std::vector<Slice> FileSlices(const Scan& scan, const std::vector<std::string>& files, SeriesGeometry& g,
                              const std::string& where) {
  const std::vector<double> iop = Numbers(Value(scan, files[0], kImageOrientation));
  if (iop.size() != 6) {
    throw InputError(fmt::format("{}: {} has no usable ImageOrientationPatient", where, scan.Name(files[0])));
  }
  SetPlane(iop.data(), g);
  std::vector<Slice> out;
  for (const std::string& f : files) {
    const std::vector<double> p = Numbers(Value(scan, f, kImagePosition));
    if (p.size() != 3) {
      throw InputError(fmt::format("{}: {} has no usable ImagePositionPatient", where, scan.Name(f)));
    }
    Slice& s = out.emplace_back();
    s.file = f;
    std::copy(p.begin(), p.end(), s.position);
    s.time_keys = {Number(scan, f, kTemporalPosition), Number(scan, f, kTriggerTime),
                   Number(scan, f, kInstanceNumber)};
  }
  return out;
}

// Each frame of an enhanced multi-frame file as a slice, placed, timed and
// rescaled by its functional groups.
std::vector<Slice> FrameSlices(const std::string& file, const MultiFrame& m, SeriesGeometry& g) {
  SetPlane(m.orientation.data(), g);
  g.pixel_spacing_mm = m.pixel_spacing_mm;
  std::vector<Slice> out;
  for (std::size_t f = 0; f < m.frames.size(); ++f) {
    const Frame& frame = m.frames[f];
    Slice& s = out.emplace_back();
    s.file = file;
    s.frame = int(f);
    std::copy(frame.position.begin(), frame.position.end(), s.position);
    s.time_keys = {frame.temporal_position_index, frame.trigger_delay_ms, double(f + 1)};
    s.rescale_slope = frame.rescale_slope;
    s.rescale_intercept = frame.rescale_intercept;
  }
  return out;
}

// Sorts `all` along their normal and checks the spacing: gantry tilt is
// measured, duplicate positions and uneven gaps refused. Several slices at
// every position are phases (OrderPhases, by `keys`); the geometry is the
// first phase's; a stack of one position is `thickness_mm` thick (1 mm where
// 0). Sets `out`'s geometry and phases.
void CheckGeometry(const Scan& scan, std::vector<Slice> all, const TimeKeys& keys, double thickness_mm,
                   bool resample_uneven, SortedSeries& out) {
  const std::string& where = out.shown;
  SeriesGeometry& g = out.geometry;
  for (Slice& s : all) s.along_normal = Dot3(s.position, g.normal);
  std::sort(all.begin(), all.end(), [](const Slice& a, const Slice& b) {
    if (a.along_normal != b.along_normal) return a.along_normal < b.along_normal;
    return a.file != b.file ? a.file < b.file : a.frame < b.frame;
  });
  std::vector<Position> positions = GroupPositions(all);
  if (positions.size() < all.size()) OrderPhases(scan, keys, positions, out);
  const std::size_t phases = positions.front().size();
  out.phases.assign(phases, {});
  for (const Position& p : positions) {
    g.slices.push_back(p.front());
    for (std::size_t k = 0; k < phases; ++k) out.phases[k].push_back(p[k]);
  }
  if (g.slices.size() < 2) {
    g.slice_gap_mm = thickness_mm > 0 ? thickness_mm : 1.0;
    return;
  }

  std::vector<double> gaps;
  for (std::size_t i = 1; i < g.slices.size(); ++i) {
    const double gap = g.slices[i].along_normal - g.slices[i - 1].along_normal;
    if (gap < kSamePositionMm) {
      throw InputError(
          fmt::format("{}: {} and {} lie at the same position ({:.3f} mm along the normal): duplicate slices "
                      "or several acquisitions in one series",
                      where, scan.Name(g.slices[i - 1]), scan.Name(g.slices[i]), g.slices[i].along_normal));
    }
    gaps.push_back(gap);
  }
  std::vector<double> sorted = gaps;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  g.slice_gap_mm = sorted[sorted.size() / 2];
  for (std::size_t i = 0; i < gaps.size(); ++i) {
    if (std::abs(gaps[i] - g.slice_gap_mm) <= kGapTolerance * g.slice_gap_mm) continue;
    if (!resample_uneven) {
      throw InputError(
          fmt::format("{}: uneven slice spacing: {:.3f} mm between {} and {} where the series' gap is {:.3f} "
                      "mm (missing slices?); cinevol loads it resampled onto an even grid when asked to "
                      "(--resample-uneven)",
                      where, gaps[i], scan.Name(g.slices[i]), scan.Name(g.slices[i + 1]), g.slice_gap_mm));
    }
    g.uneven = true;
  }
  if (g.uneven) {
    const auto largest = std::max_element(gaps.begin(), gaps.end()) - gaps.begin();
    g.largest_gap_mm = gaps[std::size_t(largest)];
    g.largest_gap_between = fmt::format("{} and {}", scan.Name(g.slices[std::size_t(largest)]),
                                        scan.Name(g.slices[std::size_t(largest) + 1]));
    g.slice_gap_mm = *std::min_element(gaps.begin(), gaps.end());
  }
  // Gantry tilt: the stack's direction leaves the slice normal.
  const Slice& first = g.slices.front();
  const Slice& last = g.slices.back();
  double step[3];
  for (int a = 0; a < 3; ++a) step[a] = last.position[a] - first.position[a];
  const double cos_tilt = Dot3(step, g.normal) / std::sqrt(Dot3(step, step));
  g.tilt_deg = std::acos(std::min(1.0, std::abs(cos_tilt))) * 180.0 / M_PI;
}

// The frames of the series' one enhanced multi-frame file; nothing where its
// files are single-frame, or its one file is a multi-frame image without
// functional groups (the adapter reads its frames as the slices of one
// stack). A series of several files, some multi-frame, is refused.
std::optional<MultiFrame> MultiFrameOf(const Scan& scan, const std::vector<std::string>& files) {
  std::size_t multi = 0;
  for (const std::string& f : files) multi += Number(scan, f, kNumberOfFrames).value_or(1) > 1;
  if (multi == 0) return std::nullopt;
  if (files.size() > 1) {
    throw InputError(fmt::format("{}: the series holds {} files, {} of them of several frames; cinevol reads "
                                 "one multi-frame file a series, or single-frame files",
                                 scan.shown, files.size(), multi));
  }
  return ReadMultiFrame(files[0], scan.Name(files[0]));
}

bool FramesRescaledAlike(const MultiFrame& m) {
  return std::all_of(m.frames.begin(), m.frames.end(), [&](const Frame& f) {
    return f.rescale_slope == m.frames[0].rescale_slope && f.rescale_intercept == m.frames[0].rescale_intercept;
  });
}

// The largest series, or the largest with `requested` as its UID.
SeriesFiles Pick(std::vector<SeriesFiles> all, const std::string& requested, const std::string& where) {
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
      throw InputError(
          fmt::format("{}: {} has Photometric Interpretation '{}'; cinevol reads grey-scale series "
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

// The first slice's patient and study fields, for the reading view's corners.
reader::Identity IdentityOf(const Scan& scan, const std::string& file) {
  reader::Identity id;
  id.set_patient_name(Value(scan, file, kPatientName));
  id.set_patient_id(Value(scan, file, kPatientId));
  id.set_study_date(Value(scan, file, kStudyDate));
  id.set_study_description(Value(scan, file, kStudyDescription));
  id.set_series_description(Value(scan, file, kSeriesDescription));
  return id;
}

// The first of the file's windows (both tags may hold several, "40\\400"):
// {center, width}, or empty when either is missing, not a number, or the
// width is below 1 (DICOM requires >= 1).
std::vector<double> StoredWindow(const Scan& scan, const std::string& file) {
  const std::vector<double> centers = Numbers(Value(scan, file, kWindowCenter));
  const std::vector<double> widths = Numbers(Value(scan, file, kWindowWidth));
  if (centers.empty() || widths.empty() || !(widths[0] >= 1)) return {};
  return {centers[0], widths[0]};
}

// The first item of the file's Radiopharmaceutical Information Sequence
// (0054,0016): its dose, half life and start time into `pet`. GDCM reads the
// header up to the sequence, or the first element past it (Pixel Data where
// nothing lies between); a file without it leaves `pet`'s fields empty. This
// is the scanner's read (ScanFiles), which went on to a later tag, stopped
// sooner. Not ReadSelectedTags, which seeks back over the element past the
// sequence, nor a skipped tag, which seeks past it: a deflated data set's
// stream can do neither, and GDCM asserts (every Deflated PET without the
// sequence aborted; found by fuzz_dicom).
void ReadRadiopharmaceutical(const std::string& file, reader::PetDose& pet) {
  gdcm::Reader reader;
  reader.SetFileName(file.c_str());
  if (!reader.ReadUpToTag(kRadiopharmaceuticalInformation)) return;
  const gdcm::DataSet& ds = reader.GetFile().GetDataSet();
  if (!ds.FindDataElement(kRadiopharmaceuticalInformation)) return;
  const gdcm::SmartPointer<gdcm::SequenceOfItems> sq =
      ds.GetDataElement(kRadiopharmaceuticalInformation).GetValueAsSQ();
  if (!sq || sq->GetNumberOfItems() < 1) return;
  const gdcm::DataSet& item = sq->GetItem(1).GetNestedDataSet();
  const auto text = [&](const gdcm::Tag& tag) {
    if (!item.FindDataElement(tag)) return std::string();
    const gdcm::ByteValue* v = item.GetDataElement(tag).GetByteValue();
    return v ? Trimmed(v->GetPointer(), v->GetLength()) : std::string();
  };
  const auto number = [&](const gdcm::Tag& tag) {
    const std::vector<double> v = Numbers(text(tag));
    return v.size() == 1 ? v[0] : 0.0;
  };
  pet.set_total_dose_bq(number(kRadionuclideTotalDose));
  pet.set_half_life_s(number(kRadionuclideHalfLife));
  pet.set_injection_time(text(kRadiopharmaceuticalStartTime));
  pet.set_injection_datetime(text(kRadiopharmaceuticalStartDateTime));
}

// A key that orders DICOM dates and times (DA "YYYYMMDD", TM "HHMMSS.FFFFFF"
// with its later parts optional, or the old "HH:MM:SS") in time.
std::string AcquisitionOrder(const std::string& date, const std::string& time) {
  std::string t;
  for (char c : time) {
    if (c != ':') t += c;
  }
  const std::size_t dot = std::min(t.find('.'), t.size());
  if (dot < 6) t.insert(dot, 6 - dot, '0');
  return date + "|" + t;
}

// A PET's attributes for SUVbw, as its files say them: the first slice's,
// and the acquisition date and time of the series' earliest file (the scan's
// start where the series time is later: the parent's io/suv.h decides).
reader::PetDose PetDoseOf(const Scan& scan, const std::vector<std::string>& files, const std::string& first) {
  reader::PetDose pet;
  pet.set_units(Value(scan, first, kUnits));
  pet.set_decay_correction(Value(scan, first, kDecayCorrection));
  pet.set_corrected_image(Value(scan, first, kCorrectedImage));
  const std::optional<double> weight = Number(scan, first, kPatientWeight);
  pet.set_patient_weight_kg(weight.value_or(0.0));
  pet.set_series_date(Value(scan, first, kSeriesDate));
  pet.set_series_time(Value(scan, first, kSeriesTime));
  const std::string* earliest = nullptr;
  std::string earliest_key;
  for (const std::string& f : files) {
    if (Value(scan, f, kAcquisitionTime).empty()) continue;
    const std::string key = AcquisitionOrder(Value(scan, f, kAcquisitionDate), Value(scan, f, kAcquisitionTime));
    if (earliest && key >= earliest_key) continue;
    earliest = &f;
    earliest_key = key;
  }
  if (earliest) {
    pet.set_acquisition_date(Value(scan, *earliest, kAcquisitionDate));
    pet.set_acquisition_time(Value(scan, *earliest, kAcquisitionTime));
  }
  ReadRadiopharmaceutical(first, pet);
  return pet;
}

}  // namespace

double Dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

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

std::string Trimmed(const char* bytes, std::size_t length) {
  std::string s(bytes, length);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  return s;
}

std::string Describe(const reader::Series& s) {
  return fmt::format("{} '{}' ({}, {} pixels, {} files)", s.uid().empty() ? "(no SeriesInstanceUID)" : s.uid(),
                     s.description(), s.modality(), s.size(), s.file_count());
}

reader::SeriesList ListSeries(const std::vector<reader::DicomFile>& files, const reader::ReadOptions& options) {
  Scan scan;
  ScanFiles(files, options, scan);
  reader::SeriesList out;
  for (const SeriesFiles& s : GroupSeries(scan)) *out.add_series() = s.info;
  return out;
}

SortedSeries ChooseSeries(const std::vector<reader::DicomFile>& files, const std::string& series_uid,
                          const reader::ReadOptions& options) {
  Scan scan;
  ScanFiles(files, options, scan);
  const SeriesFiles series = Pick(GroupSeries(scan), series_uid, scan.shown);
  SortedSeries sorted;
  sorted.shown = scan.shown;
  sorted.info = series.info;
  const std::optional<MultiFrame> multi = MultiFrameOf(scan, series.files);
  if (multi) {
    CheckGeometry(scan, FrameSlices(series.files[0], *multi, sorted.geometry), kFrameTimeKeys,
                  multi->slice_thickness_mm, options.resample_uneven, sorted);
  } else {
    const std::vector<double> thickness = Numbers(Value(scan, series.files[0], kSliceThickness));
    CheckGeometry(scan, FileSlices(scan, series.files, sorted.geometry, scan.shown), kFileTimeKeys,
                  thickness.size() == 1 ? thickness[0] : 0.0, options.resample_uneven, sorted);
  }
  CheckGreyScale(scan, series.files, scan.shown);
  const std::string& first = sorted.phases.front().front().file;
  sorted.modality = Value(scan, first, kModality);
  sorted.multi_frame = multi.has_value();
  sorted.rescaled_alike = multi ? FramesRescaledAlike(*multi) : SameRescale(scan, series.files);
  sorted.identity = IdentityOf(scan, first);
  sorted.stored_window = multi ? multi->window : StoredWindow(scan, first);
  sorted.frame_of_reference_uid = Value(scan, first, kFrameOfReference);
  if (sorted.modality == "PT") sorted.pet = PetDoseOf(scan, series.files, first);
  return sorted;
}

}  // namespace cinevol::formats::dicom
