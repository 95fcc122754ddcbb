// DICOM SEG as a volume's labels: the files a load may open, the reader
// cage's answer made a LabelVolume, CIELab made sRGB.
#include "io/dicom_seg.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "io/file_checks.h"
#include "io/formats/dicom/folder.h"
#include "io/label_volume.h"
#include "io/reader_cage.h"

namespace fs = std::filesystem;

namespace cinevol {
namespace {

double LabInverse(double t) { return t > 6.0 / 29.0 ? t * t * t : 3 * (6.0 / 29.0) * (6.0 / 29.0) * (t - 4.0 / 29.0); }

double Gamma(double linear) {
  linear = std::clamp(linear, 0.0, 1.0);
  return linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1 / 2.4) - 0.055;
}

}  // namespace

bool IsDicomSegmentation(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) return true;
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (extension == ".dcm") return true;
  if (!file_checks::IsRegularFile(path)) return false;
  const std::string head = file_checks::ReadHead(path, 132, path.filename().string());
  return head.size() == 132 && head.compare(128, 4, "DICM") == 0;
}

Vec3f DicomLabToRgb(const std::array<std::uint16_t, 3>& lab) {
  const double l = lab[0] * 100.0 / 65535.0, a = lab[1] * 255.0 / 65535.0 - 128, b = lab[2] * 255.0 / 65535.0 - 128;
  const double fy = (l + 16) / 116, fx = fy + a / 500, fz = fy - b / 200;
  const double x = 0.950456 * LabInverse(fx), y = LabInverse(fy), z = 1.088754 * LabInverse(fz);
  const double r = 3.2406 * x - 1.5372 * y - 0.4986 * z;
  const double g = -0.9689 * x + 1.8758 * y + 0.0415 * z;
  const double bl = 0.0557 * x - 0.2040 * y + 1.0570 * z;
  return {float(Gamma(r)), float(Gamma(g)), float(Gamma(bl))};
}

LabelVolume LoadSegmentation(const fs::path& path, const Volume& image, const LoadPolicy& policy) {
  LoadPolicy labelled = policy;
  labelled.label = file_checks::Shown(path, policy);
  const std::string& shown = labelled.label;
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) throw InputError(fmt::format("{}: no such file", shown));
  std::vector<reader_cage::Input> inputs;
  if (fs::is_directory(status)) {
    inputs = formats::dicom::FolderFiles(path, labelled, shown);
    if (inputs.empty()) throw InputError(fmt::format("{}: a folder without files", shown));
  } else {
    file_checks::RequireRegularFile(path, shown);
    file_checks::RequireInsideRoots(path, labelled, shown);
    inputs.push_back({path, path.filename().string()});
  }
  if (!image.metadata().orientation_override.empty()) {
    throw InputError(
        fmt::format("{}: the volume was read with the orientation {} over its files', so its patient "
                    "coordinates are not the ones a DICOM SEG's frames are placed in; load it without "
                    "an orientation",
                    shown, image.metadata().orientation_override));
  }
  reader_cage::SegmentationRead read = reader_cage::ReadSegmentation(inputs, image, labelled);
  LabelVolume out;
  out.dims = image.dims();
  out.source = shown;
  out.labels = std::move(read.labels);
  for (std::uint16_t label : out.labels) ++out.voxels[label];
  for (const reader_cage::SegmentationRead::Segment& s : read.segments) {
    out.names[s.number] = s.label.empty() ? fmt::format("segment {}", s.number) : s.label;
    if (s.has_cielab) out.colors[s.number] = DicomLabToRgb(s.cielab);
  }
  out.note = fmt::format("DICOM SEG ({}, {} segments, {} frames) placed nearest-neighbour onto the volume's grid",
                         read.type, read.segments.size(), read.frames);
  if (read.type == "FRACTIONAL") out.note += "; a pixel counts where it holds at least half the maximum fraction";
  for (const std::string& note : read.notes) out.note += "; " + note;
  if (image.metadata().frame_of_reference_uid.empty()) {
    out.note += "; the volume names no frame of reference: placed by patient coordinates alone";
  }
  AddShells(out);
  return out;
}

}  // namespace cinevol
