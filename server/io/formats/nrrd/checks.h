// Inside the reader cage: what stands in front of teem (ITK's NRRD reader).
// Header lines teem's fixed buffers cannot hold, payloads it would leak on,
// and the rewrites that let it read what it would refuse or must not open
// by itself: a header naming where the cage placed its data files, a whole
// file gzipped (.nrrd.gz).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace itk {
class ImageIOBase;
}

namespace cinevol::formats::nrrd {

// Throws InputError for a per-axis field line longer than teem's buffers.
void CheckHeaderText(const std::filesystem::path& path, const std::string& shown);

// Whether the header states where its axes point ("space" or "space
// directions"); without either, teem's reader assumes one.
bool StatesOrientation(const std::filesystem::path& path, const std::string& shown);

// "" when the file (attached voxels) or its one data file holds every voxel
// `io` (the header as ITK read it) expects, as teem will read them; else
// what is wrong. Lists and patterns are not checked.
std::string PayloadProblem(itk::ImageIOBase& io, const std::filesystem::path& path, const std::string& shown);

// The text of a header whose other files are where the cage placed them
// (`named`, in the header's order) and, with `drop_space`, without its
// `space` line. Attached voxels are read from `header` itself past its lines.
std::string RewrittenHeader(const std::filesystem::path& header, const std::vector<std::filesystem::path>& named,
                            bool drop_space, const std::string& shown);

// Whether ITK refused the header for giving both `space` and per-axis
// `spacings` (`description`: the exception's), which RewrittenHeader's
// `drop_space` mends.
bool IsSpaceWithSpacingsError(const std::string& description);

// Whether `path` is a whole NRRD file gzipped (.nrrd.gz).
bool IsGzipped(const std::filesystem::path& path);

// The detached header teem reads a gzipped NRRD through: the file itself as
// its gzip-encoded data, with a byte skip past the header.
std::string GzippedRewrite(const std::filesystem::path& path, const std::string& shown);

}  // namespace cinevol::formats::nrrd
