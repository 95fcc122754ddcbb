// NIfTI-1/-2 and Analyze 7.5, without a NIfTI library: which other files a
// header's reader opens. A single file ("n+1", "n+2") holds its voxels; a
// pair keeps them in an .img beside the .hdr, found by name.
#pragma once

#include <filesystem>
#include <string>

#include "io/formats/format.h"

namespace cinevol::formats::nifti {

// Whether a (lower-case) name ending is a pair's: .hdr or .img, gzipped or not.
bool IsPairName(const std::string& ending);

// Every sibling the readers could take for the other half of a pair (.hdr,
// .img, .nii, any case, gzipped or not): they find one from the other by name.
formats::References PairReferences(const std::filesystem::path& file);

// A .nii or .nia file: nothing when its header says it holds its voxels, its
// pair's siblings when it says "ni1"/"ni2" or is Analyze. The header is read
// through zlib (.nii.gz).
formats::References FindReferences(const std::filesystem::path& file);

}  // namespace cinevol::formats::nifti
