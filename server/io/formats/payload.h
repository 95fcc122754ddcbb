// Inside the reader cage: the payload check the uncompressed raw formats
// (MetaImage, binary VTK) share. Their ITK readers warn about a short payload
// on stderr and carry on.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

namespace cinevol::formats {

// "" when `data` (the file named `file` itself, or another) holds at least
// `expected` voxel bytes past its first `skip` bytes, else what is wrong.
std::string UncompressedPayloadProblem(const std::filesystem::path& data, const std::filesystem::path& file,
                                       std::int64_t skip, std::int64_t expected);

}  // namespace cinevol::formats
