// NRRD and NHDR headers as teem reads them, without teem: the fields, and the
// files a "data file" field names (one file, a LIST, or a pattern). The parent
// checks those files against the load's policy; the child rewrites the header
// to name where the cage placed them (checks.h).
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "io/formats/format.h"

namespace cinevol::formats::nrrd {

// A NRRD header as teem reads it, for the lenient rewrite.
struct Header {
  std::vector<std::string> lines;  // magic and fields, without the data file field and its list
  std::size_t line_count = 0;      // lines teem reads up to the data (blank line included)
  bool attached = true;            // no data file field: the voxels follow the header
  bool listed = false;             // LIST or pattern form (else a single file)
  std::string list_dim;            // LIST or pattern form: the data file dimension if given
  formats::References references;
};

// Whether `file` starts with the magic "NRRD": teem reads any such file,
// whatever its name says.
bool HasMagic(const std::filesystem::path& file, const std::string& shown);

// Parses the (bounded) header of a file that starts with "NRRD".
Header ParseHeader(const std::filesystem::path& file, const std::string& shown);

// The field name of a "name: value" header line, lower case and without
// blanks ("data file" -> "datafile"); "" for comments and other lines.
std::string FieldName(const std::string& line);

}  // namespace cinevol::formats::nrrd
