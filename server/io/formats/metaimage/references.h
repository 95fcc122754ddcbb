// MetaImage (.mha, .mhd) headers, without MetaIO: the files its
// "ElementDataFile" names. LOCAL (the voxels follow), a file, "LIST" (file
// names follow), or a pattern; it is the header's last field.
#pragma once

#include <filesystem>
#include <string>

#include "io/formats/format.h"

namespace cinevol::formats::metaimage {

// Whether an ElementDataFile value says the voxels follow the header.
bool IsLocal(const std::string& value);

// The files `file`'s ElementDataFile names, from its (bounded) header.
formats::References FindReferences(const std::filesystem::path& file, const std::string& shown);

}  // namespace cinevol::formats::metaimage
