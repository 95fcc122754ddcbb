// Inside the reader cage: what stands in front of MetaIO (ITK's MetaImage
// reader). Header text its fixed buffers cannot hold, payloads it would read
// short or inflate unchecked, the rewrite that names where the cage placed
// the data files, and the data file MetaIO itself settled on.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace itk {
class ImageIOBase;
}

namespace cinevol::formats::metaimage {

// Throws InputError for a header MetaIO would overflow or loop on: a run of
// 255 characters between separators, a line with no '=' (MetaIO would read
// the next one as its value), an NDims outside 1 to 10.
void CheckHeaderText(const std::filesystem::path& path, const std::string& shown);

// Whether the header states where its axes point (TransformMatrix,
// Orientation or Rotation); without one, MetaIO assumes the identity.
bool StatesOrientation(const std::filesystem::path& path, const std::string& shown);

// The text of a header whose ElementDataFile names where the cage placed the
// files (`named`, in the header's order): a single file, or a LIST.
std::string RewrittenHeader(const std::filesystem::path& header, const std::vector<std::filesystem::path>& named,
                            const std::string& shown);

// Throws InputError unless the data file MetaIO read from the header (`io`)
// is one the cage placed (`placed`), or the file itself (LOCAL).
void CheckDataFile(itk::ImageIOBase& io, const std::filesystem::path& path,
                   const std::vector<std::filesystem::path>& placed, const std::string& shown);

// "" when the data file (or the file past its header) holds every voxel `io`
// expects, as MetaIO will read them, compressed or not; else what is wrong.
std::string PayloadProblem(itk::ImageIOBase& io, const std::filesystem::path& path, const std::string& shown);

// "CT" or "MR" when the header's Modality says so, else "".
std::string Modality(itk::ImageIOBase& io);

}  // namespace cinevol::formats::metaimage
