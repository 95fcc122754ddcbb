// Uncompressed payloads: the file must be as long as the voxels.
#include "io/formats/payload.h"

#include <algorithm>

#include <fmt/format.h>

#include "io/file_checks.h"

namespace fs = std::filesystem;

namespace cinevol::formats {

std::string UncompressedPayloadProblem(const fs::path& data, const fs::path& file, std::int64_t skip,
                                       std::int64_t expected) {
  std::error_code ec;
  const auto size = file_checks::IsRegularFile(data) ? fs::file_size(data, ec) : 0;
  if (ec || !file_checks::IsRegularFile(data)) return "cannot read the file that ElementDataFile names";
  if (std::int64_t(size) - skip < expected) {
    return fmt::format("truncated: {} voxel bytes expected, {} holds {}", expected,
                       data == file ? (skip > 0 ? "the file after its header" : "the file")
                                    : fmt::format("'{}'", data.filename().string()),
                       std::max<std::int64_t>(0, std::int64_t(size) - skip));
  }
  return "";
}

}  // namespace cinevol::formats
