// Inside the reader cage: what stands in front of GDCM's parser, which trusts
// a DICOM file's structure: it asserts (aborting the process) on a file meta
// element whose VR it does not know, allocates whatever length an element
// declares, and decodes a JPEG 2000 or RLE stream that disagrees with the
// header past its buffers.
#pragma once

#include <filesystem>
#include <string>

namespace cinevol::formats::dicom {

// What keeps `path` from being what GDCM can parse, walked here (headers
// only, nested sequences included, in the encoding its transfer syntax
// names): every VR known, every defined length inside the file, a pixel
// module that holds together and compressed frames that describe the image
// the header does. Empty where the file is sound. A file that fails is
// not handed to GDCM (it counts as not DICOM).
std::string StructureProblem(const std::filesystem::path& path);

}  // namespace cinevol::formats::dicom
