// Loads volumes into memory: files (NIfTI, NRRD/NHDR, MetaImage, VTK legacy)
// and DICOM series through ITK/GDCM, and the built-in phantoms. Every failure
// throws InputError naming the file or folder and what was wrong.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "cinevol/v1/scene.pb.h"
#include "core/volume.h"

namespace cinevol {

// How far one reader child (io/reader_cage.h) may go.
struct ReaderLimits {
  // The child's address space (bytes, its libraries included) until its
  // header is read; for the voxels it gets twice their bytes more.
  std::uint64_t header_address_space = std::uint64_t{2} << 30;
  double cpu_seconds = 120;   // the child's CPU time (--reader-cpu-seconds)
  double wall_seconds = 300;  // from its start to its last answer (--reader-seconds)
};

// What a load may read besides the file or folder it names, and how much.
// Only regular files are ever opened (FIFOs, devices and sockets are refused
// without opening them), and headers are read with a bound.
struct LoadPolicy {
  enum class References {
    kAnywhere,     // the operator's own files (--volume): a header may name any file
    kInsideRoots,  // files a header names must resolve (symlinks followed) inside `roots`
    kNone,         // uploads: a header that names another file is refused
  };
  References references = References::kAnywhere;
  std::vector<std::filesystem::path> roots;  // canonical; for kInsideRoots
  // Voxels per volume, checked on the header before any voxel is read. The
  // default is 1024^3; core's kMaxVoxels (the same number) bounds it anyway.
  std::uint64_t max_voxels = std::uint64_t{1} << 30;
  // Names the file in messages instead of its path ("upload:head.nrrd");
  // empty: the path.
  std::string label;
  ReaderLimits reader;
  // Called once the header is read and before any voxel is, with what the
  // volume will hold (Volume::BytesToLoad): throws to refuse the load (a
  // memory limit), else the bytes count as reserved until the caller says.
  std::function<void(std::uint64_t bytes)> reserve;
  // Once raised, the load stops within a second (Cancelled).
  const std::atomic<bool>* cancel = nullptr;
  // A DICOM series with uneven slice gaps is resampled onto an even grid at
  // its smallest gap (a note names the largest) instead of refused.
  bool resample_uneven = false;
};

// Loads what `source` names, every phase of a time series (a 4-D file, a
// DICOM series of several phases); relative paths resolve against
// `base_dir`; source.orientation overrides the file's.
VolumeSeries LoadVolumeSeries(const v1::VolumeSource& source, const std::filesystem::path& base_dir = {},
                              const LoadPolicy& policy = {});
// The same where one volume is wanted: a time series is refused, naming it.
// So are LoadVolumeFile's and LoadDicomSeries'.
Volume LoadVolume(const v1::VolumeSource& source, const std::filesystem::path& base_dir = {},
                  const LoadPolicy& policy = {});

// The direction of orientation code `code` ("LPI"); InputError naming
// `field` unless it is one.
std::array<double, 9> ParseOrientation(const std::string& code, const std::string& field);
// Reorients `volume` to `code` when it is not empty (an override of the file's).
void ApplyOrientation(Volume& volume, const std::string& code, const std::string& field);

// Reads a command-line volume spec: "phantom:NAME[?key=value&...]" (keys:
// size, spacing, value, background, radius), a folder (a DICOM series) or a file.
v1::VolumeSource ParseVolumeSpec(std::string_view spec);

// One volume file, in any format ITK reads that cinevol accepts.
Volume LoadVolumeFile(const std::filesystem::path& path, const LoadPolicy& policy = {});

// A DICOM series found in a folder.
struct DicomSeriesInfo {
  std::string uid;
  std::string description;
  std::string modality;
  std::string size;  // columns x rows
  std::size_t file_count = 0;
};

// The series in `folder` (searched recursively), largest first. Only regular
// files are looked at.
std::vector<DicomSeriesInfo> ListDicomSeries(const std::filesystem::path& folder, const LoadPolicy& policy = {});

// Loads one series from `folder`: `series_uid`, or the largest when empty.
// Slices are sorted along the slice normal; gantry tilt, uneven gaps (missing
// slices), mixed sizes or orientations and duplicate positions are refused,
// and so is a series of several phases (positions that repeat alike), which
// LoadVolumeSeries reads.
Volume LoadDicomSeries(const std::filesystem::path& folder, const std::string& series_uid = {},
                       const LoadPolicy& policy = {});

}  // namespace cinevol
