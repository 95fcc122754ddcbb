// Internal to server/io: what a volume load may open. Everything the loaders
// open themselves goes through here first: only regular files, headers read
// with a bound, and the other files a header names found and checked against
// the LoadPolicy before ITK reads anything.
#pragma once

#include <cstddef>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "io/volume_loader.h"

namespace cinevol::file_checks {

// The most header text read to find the files a header names; real headers
// are a few KiB, a NRRD list of slice files a few hundred.
inline constexpr std::size_t kMaxHeaderBytes = std::size_t{1} << 20;

// What messages call `path`: the policy's label when it has one.
std::string Shown(const std::filesystem::path& path, const LoadPolicy& policy);

// Whether `path`, symlinks followed, is a regular file. Looks with stat and
// never opens it: opening a FIFO for reading blocks until a writer comes.
bool IsRegularFile(const std::filesystem::path& path);

// Throws InputError "<shown>: not a regular file" unless IsRegularFile.
void RequireRegularFile(const std::filesystem::path& path, const std::string& shown);

// Opens a regular file for reading without blocking on anything else (the
// type is checked on the open descriptor, so a file swapped after
// IsRegularFile is refused too). Returns -1 if it cannot.
int OpenRegularFile(const std::filesystem::path& path);

// OpenRegularFile as a stdio stream, closed when dropped; null if it cannot.
using FileStream = std::unique_ptr<std::FILE, int (*)(std::FILE*)>;
FileStream OpenRegularStream(const std::filesystem::path& path);

// At most `limit` bytes from the start of a regular file.
std::string ReadHead(const std::filesystem::path& path, std::size_t limit, const std::string& shown);

// Whether `path` (canonical) lies in one of `roots` (canonical).
bool IsInside(const std::filesystem::path& path, const std::vector<std::filesystem::path>& roots);

// kInsideRoots: throws InputError "<shown>: outside the data roots" unless
// `path`, symlinks followed, lies inside one of the policy's roots.
void RequireInsideRoots(const std::filesystem::path& path, const LoadPolicy& policy, const std::string& shown);

// The field name of a "name: value" header line, lower case and without
// blanks ("data file" -> "datafile"); "" for comments and other lines.
std::string FieldName(const std::string& line);

// The other files a volume file's header names.
struct References {
  std::string field;                        // "data file", "ElementDataFile", ...; empty: none
  std::vector<std::filesystem::path> files;  // resolved against the header's folder
  std::string problem;                      // why `files` could not be listed; "" when they were
};

// A NRRD header as teem reads it, for the lenient rewrite.
struct NrrdHeader {
  std::vector<std::string> lines;  // magic and fields, without the data file field and its list
  std::size_t line_count = 0;      // lines teem reads up to the data (blank line included)
  bool attached = true;            // no data file field: the voxels follow the header
  bool listed = false;             // LIST or pattern form (else a single file)
  std::string list_dim;            // LIST or pattern form: the data file dimension if given
  References references;
};

// Parses the (bounded) header of a file that starts with "NRRD".
NrrdHeader ParseNrrdHeader(const std::filesystem::path& file, const std::string& shown);

// Finds the files `file`'s header names (NRRD/NHDR "data file", MetaImage
// "ElementDataFile", a NIfTI/Analyze .hdr/.img pair), reading only `file`.
References FindReferences(const std::filesystem::path& file, const std::string& shown);

// Throws InputError unless `refs` is what `policy` allows: kNone refuses any
// reference; kInsideRoots needs each file to be regular and inside the roots.
// Messages name `shown` and the field, never whether an outside file exists.
void CheckReferences(const References& refs, const LoadPolicy& policy, const std::string& shown);

}  // namespace cinevol::file_checks
