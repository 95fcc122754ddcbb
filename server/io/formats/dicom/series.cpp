// DICOM series: GDCM scans the headers, cinevol groups, sorts and checks them.
#include "io/formats/dicom/series.h"

#include <fmt/format.h>
#include <gdcmReader.h>
#include <gdcmScanner.h>
#include <gdcmSequenceOfItems.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <sstream>

#include "core/error.h"
#include "core/volume.h"
#include "io/formats/dicom/checks.h"

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

// What orders a position's files in time, the first every file of the series
// has: the Temporal Position Identifier, else the Trigger Time, else the
// Instance Number.
struct TimeKey {
  gdcm::Tag tag;
  const char* name;
  const char* unit;
};
const TimeKey kTimeKeys[] = {{kTemporalPosition, "Temporal Position Identifier", ""},
                             {kTriggerTime, "Trigger Time", " ms"},
                             {kInstanceNumber, "Instance Number", ""}};

// Slices whose positions along the normal differ by more than this fraction
// of the typical gap count as unevenly spaced.
constexpr double kGapTolerance = 0.01;

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

// Scans `files`' headers. Files whose structure is not sound DICOM are
// left out (with the pre-checks on), and so are files GDCM cannot parse.
void ScanFiles(const std::vector<reader::DicomFile>& files, const reader::ReadOptions& options, Scan& scan) {
  scan.shown = options.shown;
  scan.files_seen = files.size();
  std::vector<std::string> sound;
  for (const reader::DicomFile& f : files) {
    scan.names[f.path] = f.name;
    if (!options.prechecks || StructureIsSound(f.path)) sound.push_back(f.path);
  }
  for (const gdcm::Tag& t : {kSeriesUid, kSeriesDescription, kModality, kImagePosition, kImageOrientation, kRows,
                             kColumns, kSliceThickness, kPhotometric, kRescaleIntercept, kRescaleSlope, kWindowCenter,
                             kWindowWidth, kPatientName, kPatientId, kStudyDate, kStudyDescription,
                             kFrameOfReference, kTemporalPosition, kTriggerTime, kInstanceNumber}) {
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

// A time series (several files at a position): each position's files ordered
// in time by the first of kTimeKeys every file has; refused where two files
// of a position have the same time (or nothing orders them), where positions
// hold different counts, or where there are more than kMaxPhases phases. Sets
// `out`'s phase order and times.
void OrderPhases(const Scan& scan, const std::vector<std::string>& files, std::vector<Position>& positions,
                 SortedSeries& out) {
  const std::string& where = out.shown;
  const TimeKey* key = nullptr;
  std::map<std::string, double> time;  // file -> its value of `key`
  for (const TimeKey& k : kTimeKeys) {
    std::map<std::string, double> values;
    for (const std::string& f : files) {
      const std::optional<double> v = Number(scan, f, k.tag);
      if (!v) break;
      values[f] = *v;
    }
    if (values.size() == files.size()) {
      key = &k;
      time = std::move(values);
      break;
    }
  }
  // Two files of one position at one time are duplicates, whatever the counts.
  for (Position& p : positions) {
    if (key) {
      std::stable_sort(p.begin(), p.end(), [&](const Slice& a, const Slice& b) { return time[a.file] < time[b.file]; });
    }
    for (std::size_t i = 1; i < p.size(); ++i) {
      if (key && time[p[i].file] != time[p[i - 1].file]) continue;
      throw InputError(fmt::format(
          "{}: {} and {} lie at the same position ({:.3f} mm along the normal): duplicate slices or several "
          "acquisitions in one series ({})",
          where, scan.Name(p[i - 1].file), scan.Name(p[i].file), p[i].along_normal,
          key ? fmt::format("both with {} {:g}{}", key->name, time[p[i].file], key->unit)
              : std::string("no Temporal Position Identifier, Trigger Time or Instance Number orders them in time")));
    }
  }
  // The most common count is the series' phases; a position holding another
  // is named.
  std::map<std::size_t, std::size_t> positions_holding;  // files -> positions holding that many
  for (const Position& p : positions) ++positions_holding[p.size()];
  const std::size_t phases =
      std::max_element(positions_holding.begin(), positions_holding.end(),
                       [](const auto& a, const auto& b) { return a.second < b.second; })->first;
  for (const Position& p : positions) {
    if (p.size() == phases) continue;
    throw InputError(fmt::format("{}: positions hold {} and {} files: not one phase a position ({} files at {:.3f} mm "
                                 "along the normal, {} among them; a phase missing, or another acquisition?)",
                                 where, phases, p.size(), p.size(), p.front().along_normal, scan.Name(p.front().file)));
  }
  if (phases > std::size_t(kMaxPhases)) {
    throw InputError(fmt::format("{}: a time series of {} phases ({} files at each of {} position{}); cinevol "
                                 "reads 1 to {}",
                                 where, phases, phases, positions.size(), positions.size() == 1 ? "" : "s",
                                 kMaxPhases));
  }
  out.phase_order = key->name;
  // Each phase's time: the mean of its files' Trigger Times, where every file
  // has one and the means rise phase by phase.
  std::vector<double> seconds(phases, 0.0);
  for (const Position& p : positions) {
    for (std::size_t k = 0; k < phases; ++k) {
      const std::optional<double> ms = Number(scan, p[k].file, kTriggerTime);
      if (!ms) return;
      seconds[k] += *ms / 1000.0 / double(positions.size());
    }
  }
  for (std::size_t k = 1; k < phases; ++k) {
    if (!(seconds[k] > seconds[k - 1])) return;
  }
  out.phase_seconds = std::move(seconds);
}

// Sorts `files` along their normal and checks the spacing: gantry tilt is
// measured, duplicate positions and uneven gaps refused. Several files at
// every position are phases (OrderPhases); the geometry is the first phase's.
// Sets `out`'s geometry and phases.
void CheckGeometry(const Scan& scan, const std::vector<std::string>& files, bool resample_uneven, SortedSeries& out) {
  const std::string& where = out.shown;
  SeriesGeometry& g = out.geometry;
  const std::vector<double> iop = Numbers(Value(scan, files[0], kImageOrientation));
  if (iop.size() != 6) {
    throw InputError(fmt::format("{}: {} has no usable ImageOrientationPatient", where, scan.Name(files[0])));
  }
  std::copy(iop.begin(), iop.begin() + 3, g.row);
  std::copy(iop.begin() + 3, iop.end(), g.col);
  g.normal[0] = g.row[1] * g.col[2] - g.row[2] * g.col[1];
  g.normal[1] = g.row[2] * g.col[0] - g.row[0] * g.col[2];
  g.normal[2] = g.row[0] * g.col[1] - g.row[1] * g.col[0];

  std::vector<Slice> all;
  for (const std::string& f : files) {
    const std::vector<double> p = Numbers(Value(scan, f, kImagePosition));
    if (p.size() != 3) {
      throw InputError(fmt::format("{}: {} has no usable ImagePositionPatient", where, scan.Name(f)));
    }
    all.push_back({f, {p[0], p[1], p[2]}, Dot3(p.data(), g.normal)});
  }
  std::sort(all.begin(), all.end(), [](const Slice& a, const Slice& b) {
    return a.along_normal < b.along_normal || (a.along_normal == b.along_normal && a.file < b.file);
  });
  std::vector<Position> positions = GroupPositions(all);
  if (positions.size() < all.size()) OrderPhases(scan, files, positions, out);
  const std::size_t phases = positions.front().size();
  out.phases.assign(phases, {});
  for (const Position& p : positions) {
    g.slices.push_back(p.front());
    for (std::size_t k = 0; k < phases; ++k) out.phases[k].push_back(p[k].file);
  }
  if (g.slices.size() < 2) {
    const std::vector<double> t = Numbers(Value(scan, files[0], kSliceThickness));
    g.slice_gap_mm = t.size() == 1 && t[0] > 0 ? t[0] : 1.0;
    return;
  }

  std::vector<double> gaps;
  for (std::size_t i = 1; i < g.slices.size(); ++i) {
    const double gap = g.slices[i].along_normal - g.slices[i - 1].along_normal;
    if (gap < kSamePositionMm) {
      throw InputError(
          fmt::format("{}: {} and {} lie at the same position ({:.3f} mm along the normal): duplicate slices "
                      "or several acquisitions in one series",
                      where, scan.Name(g.slices[i - 1].file), scan.Name(g.slices[i].file), g.slices[i].along_normal));
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
                      where, gaps[i], scan.Name(g.slices[i].file), scan.Name(g.slices[i + 1].file), g.slice_gap_mm));
    }
    g.uneven = true;
  }
  if (g.uneven) {
    const auto largest = std::max_element(gaps.begin(), gaps.end()) - gaps.begin();
    g.largest_gap_mm = gaps[std::size_t(largest)];
    g.largest_gap_between = fmt::format("{} and {}", scan.Name(g.slices[std::size_t(largest)].file),
                                        scan.Name(g.slices[std::size_t(largest) + 1].file));
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

// A DICOM string value: trailing spaces and NULs dropped.
std::string Trimmed(const char* bytes, std::size_t length) {
  std::string s(bytes, length);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  return s;
}

// The first item of the file's Radiopharmaceutical Information Sequence
// (0054,0016): its dose, half life and start time into `pet`. GDCM reads the
// header up to the sequence, never the pixels; a file without it leaves
// `pet`'s fields empty.
void ReadRadiopharmaceutical(const std::string& file, reader::PetDose& pet) {
  gdcm::Reader reader;
  reader.SetFileName(file.c_str());
  if (!reader.ReadSelectedTags({kRadiopharmaceuticalInformation})) return;
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
  CheckGeometry(scan, series.files, options.resample_uneven, sorted);
  CheckGreyScale(scan, series.files, scan.shown);
  const std::vector<std::string>& files_sorted = sorted.phases.front();
  sorted.modality = Value(scan, files_sorted[0], kModality);
  sorted.rescaled_alike = SameRescale(scan, series.files);
  sorted.identity = IdentityOf(scan, files_sorted[0]);
  sorted.stored_window = StoredWindow(scan, files_sorted[0]);
  sorted.frame_of_reference_uid = Value(scan, files_sorted[0], kFrameOfReference);
  if (sorted.modality == "PT") sorted.pet = PetDoseOf(scan, series.files, files_sorted[0]);
  return sorted;
}

}  // namespace cinevol::formats::dicom
