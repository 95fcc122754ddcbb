// Inside the reader cage: what stands in front of ITK's NIfTI reader
// (nifti1_io), which aborts on a non-finite orientation, spends minutes on an
// absurd one, and pads a short payload with zeros instead of failing.
#pragma once

#include <filesystem>
#include <string>

namespace itk {
class ImageIOBase;
}

namespace cinevol::formats::nifti {

// Throws InputError for a header (an .img's is in the .hdr beside it) whose
// spacing, orientation or scaling is not finite or beyond 10^6 mm. The
// reader takes a file by its name (.nii, .hdr, .img, any case, optionally
// .gz) and parses the header while ReadImageInformation runs, so this runs
// before that.
void CheckHeaders(const std::filesystem::path& path, const std::string& shown);

// Whether the header (an .img's is in the .hdr beside it) states where its
// axes point: a qform or sform code above 0. Analyze and NIfTI with both
// codes 0 state none, and the reader assumes one.
bool StatesOrientation(const std::filesystem::path& path);

// "" when the file (gz or plain) holds every voxel its header promises,
// else what is missing. Inflates no more than the header promises.
std::string PayloadProblem(const std::filesystem::path& path);

// The voxel type as the file stores it ("int16", "uint8 (scl_slope 2,
// scl_inter 0)", "NIfTI datatype 7") when `io`'s dictionary holds a NIfTI
// datatype; "" when it holds none.
std::string StoredType(const itk::ImageIOBase& io);

}  // namespace cinevol::formats::nifti
