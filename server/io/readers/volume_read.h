// Inside the reader cage: the volume readers (the ITK/GDCM adapter,
// itk_adapter.cpp, with each format's checks from io/formats/), each in two
// steps: the header, then the voxels into memory the caller provides, in the
// file's own type.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cinevol/reader/reader.pb.h"

namespace cinevol::reader {

// How one read goes.
struct ReadOptions {
  std::string shown;                // what messages call the input
  std::uint64_t max_voxels = 0;
  bool prechecks = true;            // the checks in front of the third-party readers
  bool resample_uneven = false;     // DICOM series: uneven slice gaps resampled, not refused
  int scratch_fd = -1;              // an empty file for a rewritten header, and its path
  std::filesystem::path scratch_path;
};

class VolumeRead {
 public:
  virtual ~VolumeRead() = default;
  const Header& header() const { return header_; }
  // Phases of a time series (1 for a still volume): header().phases or 1.
  int phases() const { return header_.phases() > 1 ? int(header_.phases()) : 1; }
  // Writes phase `phase`'s voxels (dims' product times the type's size) into
  // `memory`; a caller asks for each phase once, in order.
  virtual void Read(void* memory, std::size_t bytes, int phase) = 0;

 protected:
  Header header_;
};

// A volume file at `path` (NIfTI, NRRD/NHDR, MetaImage, VTK), where the
// files its header names are found at `named` (in the header's order).
std::unique_ptr<VolumeRead> OpenVolumeFile(const std::filesystem::path& path,
                                           const std::vector<std::filesystem::path>& named,
                                           const ReadOptions& options);

// A DICOM file: where the reader opens it, and its path under the folder.
struct DicomFile {
  std::string path;
  std::string name;
};

// One series of `files` (`series_uid`, or the largest): slices sorted along
// their normal; positions that repeat alike read as phases of a time series
// (formats/dicom/series.h); gantry tilt, uneven gaps, duplicates refused.
std::unique_ptr<VolumeRead> OpenDicomSeries(const std::vector<DicomFile>& files, const std::string& series_uid,
                                            const ReadOptions& options);

// The series `files` hold, largest first.
SeriesList ListDicomSeries(const std::vector<DicomFile>& files, const ReadOptions& options);

}  // namespace cinevol::reader
