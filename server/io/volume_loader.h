// Loads volumes into memory: files (NIfTI, NRRD/NHDR, MetaImage, VTK legacy)
// and DICOM series through ITK/GDCM, and the built-in phantoms. Every failure
// throws InputError naming the file or folder and what was wrong.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "cinevol/v1/scene.pb.h"
#include "core/volume.h"

namespace cinevol {

// Loads what `source` names; relative paths resolve against `base_dir`.
Volume LoadVolume(const v1::VolumeSource& source, const std::filesystem::path& base_dir = {});

// Reads a command-line volume spec: "phantom:NAME[?key=value&...]" (keys:
// size, spacing, value, background, radius), a folder (a DICOM series) or a file.
v1::VolumeSource ParseVolumeSpec(std::string_view spec);

// One volume file, in any format ITK reads that cinevol accepts.
Volume LoadVolumeFile(const std::filesystem::path& path);

// A DICOM series found in a folder.
struct DicomSeriesInfo {
  std::string uid;
  std::string description;
  std::string modality;
  std::string size;  // columns x rows
  std::size_t file_count = 0;
};

// The series in `folder` (searched recursively), largest first.
std::vector<DicomSeriesInfo> ListDicomSeries(const std::filesystem::path& folder);

// Loads one series from `folder`: `series_uid`, or the largest when empty.
// Slices are sorted along the slice normal; gantry tilt, uneven gaps (missing
// slices), mixed sizes or orientations and duplicate positions are refused.
Volume LoadDicomSeries(const std::filesystem::path& folder, const std::string& series_uid = {});

}  // namespace cinevol
