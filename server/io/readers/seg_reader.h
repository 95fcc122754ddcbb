// Inside the reader cage: a DICOM SEG (Segmentation Storage, binary or
// fractional) read with DCMTK's dcmdata and placed onto a volume's grid, so
// that it arrives as that volume's label volume (uint16, segment numbers as
// labels). What it reads and refuses: docs/pacs.md, "DICOM SEG".
#pragma once

#include <memory>
#include <vector>

#include "cinevol/reader/reader.pb.h"
#include "io/readers/volume_read.h"

namespace cinevol::reader {

// At most this many segments (as many as a scene may style labels).
inline constexpr int kMaxSegments = 1024;

// The SEG among `files` (one file; or a folder's, which must hold exactly
// one SEG among its DICOM files), its frames placed by their Plane Position
// and Orientation onto `target`: each voxel of the target takes the segment
// of the frame pixel nearest its centre, within half the SEG's slice spacing
// of the frame's plane (fractional: where the pixel is at least half the
// Maximum Fractional Value). The header is the target's grid with
// Header.segmentation and the SEG's frame of reference; InputError names
// what is wrong (frames outside the volume, too many segments, frame counts
// that disagree, ...). Pixel data are counted against options.max_voxels
// before they are read.
std::unique_ptr<VolumeRead> OpenSegmentation(const std::vector<DicomFile>& files, const Grid& target,
                                             const ReadOptions& options);

// Loads DCMTK's data dictionary: before the sandbox, which leaves it unreadable.
void WarmUpSegmentations();

}  // namespace cinevol::reader
