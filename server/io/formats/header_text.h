// What the text headers (NRRD, MetaImage) share: their lines as the C
// readers split them, field names, and the files a data file field names
// (one file, a LIST, or a pattern), resolved as the readers resolve them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "io/formats/format.h"

namespace cinevol::formats {

// The most header text read to find the files a header names; real headers
// are a few KiB, a NRRD list of slice files a few hundred.
inline constexpr std::size_t kMaxHeaderBytes = std::size_t{1} << 20;

// Header lines as teem and MetaIO split them: "\n", "\r\n" and a lone "\r"
// each end a line, and a NUL ends what a C reader sees of one.
std::vector<std::string> Lines(const std::string& text);

// The byte offset just past the first `lines` lines of `text`, with line ends
// counted as Lines counts them ("\n", "\r" or "\r\n"); -1 when the text has
// fewer.
std::int64_t OffsetAfterLines(const std::string& text, std::size_t lines);

// A field name lower-cased and without blanks, so that "DATA FILE",
// "datafile" and "data  file" compare equal: the check must catch every
// spelling a lenient reader might accept.
std::string NormalKey(const std::string& key);

// `s` without leading and trailing blanks and tabs.
std::string Trim(const std::string& s);
// `s` without leading and trailing blanks, tabs and carriage returns.
std::string TrimBlanks(const std::string& s);

// Adds a file a header names; relative names are relative to the header's
// folder in every format cinevol reads. "-" is standard input to teem.
void AddFile(References& refs, const std::filesystem::path& dir, const std::string& name);

// "name%03d.raw <min> <max> <step> [<dim>]" (`dim`, when given, receives the
// last). The readers hand the name to sprintf, so only a single %d with an
// optional 0 flag and width is accepted.
void AddPattern(References& refs, const std::filesystem::path& dir, const std::string& value, std::string* dim);

// Every non-empty line of `lines` from `first` on names a file (a LIST);
// `truncated`: the header was cut at kMaxHeaderBytes.
void AddList(References& refs, const std::filesystem::path& dir, const std::vector<std::string>& lines,
             std::size_t first, bool truncated);

}  // namespace cinevol::formats
