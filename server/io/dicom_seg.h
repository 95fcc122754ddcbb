// Segmentations from DICOM SEG, the parent's side: the SEG is read and its
// frames placed onto the volume's grid in the reader cage
// (readers/seg_reader.h); here its segments become the label volume's
// labels, names and colours, and the labels join the path every other
// segmentation takes (shells, the table, sessions' label styles).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>

#include "core/labels.h"
#include "core/volume.h"
#include "io/volume_loader.h"

namespace cinevol {

// Whether `path` names a DICOM SEG rather than a label volume file: a folder,
// or a file whose name ends in .dcm or that is DICOM Part 10 ("DICM" after
// its 128-byte preamble).
bool IsDicomSegmentation(const std::filesystem::path& path);

// DICOM's Recommended Display CIELab Value (L*, a*, b* scaled to 0..65535,
// PS3.3 C.10.7.1.1) as sRGB, each in [0, 1]: the D65 white point, as DCMTK's
// IODCIELabUtil and 3D Slicer read it; colours outside sRGB are clipped.
Vec3f DicomLabToRgb(const std::array<std::uint16_t, 3>& lab);

// The DICOM SEG at `path` (a file, or a folder holding one among its files)
// as `image`'s segmentation: segment numbers are the labels, segment labels
// their names ("segment N" where it has none), recommended display colours
// their colours; partial-volume shells added (AddShells). Refused (InputError
// naming the file): a SEG of an image read with an orientation override (its
// patient coordinates are not its files'), one in another frame of reference
// than the image's, one whose frames all miss the image, more than 1024
// segments, frame counts that disagree, and whatever docs/pacs.md's "The
// segmentation reader" lists.
LabelVolume LoadSegmentation(const std::filesystem::path& path, const Volume& image, const LoadPolicy& policy = {});

}  // namespace cinevol
