// NRRD headers and the files their "data file" field names.
#include "io/formats/nrrd/references.h"

#include <algorithm>

#include <fmt/format.h>

#include "io/file_checks.h"
#include "io/formats/header_text.h"

namespace fs = std::filesystem;

namespace cinevol::formats::nrrd {

bool HasMagic(const fs::path& file, const std::string& shown) {
  return file_checks::ReadHead(file, 4, shown) == "NRRD";
}

std::string FieldName(const std::string& line) {
  const std::size_t colon = line.find(':');
  return line.empty() || line[0] == '#' || colon == std::string::npos ? "" : NormalKey(line.substr(0, colon));
}

Header ParseHeader(const fs::path& file, const std::string& shown) {
  const std::string head = file_checks::ReadHead(file, kMaxHeaderBytes + 1, shown);
  const bool truncated = head.size() > kMaxHeaderBytes;
  const std::vector<std::string> lines = Lines(head);
  Header h;
  bool ended = false;
  std::size_t i = 0;
  for (; i < lines.size() && !ended; ++i) {
    const std::string& line = lines[i];
    ended = i > 0 && line.empty();  // the blank line before attached voxels
    // teem: the field name is what precedes ": ", and '#' starts a comment.
    if (i == 0 || ended || FieldName(line) != "datafile") {
      if (!ended) h.lines.push_back(line);
      continue;
    }
    const std::size_t colon = line.find(':');
    const std::string value = line.substr(std::min(line.size(), line.find_first_not_of(" \t", colon + 1)));
    h.attached = false;
    h.references.field = "data file";
    h.listed = value.rfind("LIST", 0) == 0 || value.find('%') != std::string::npos;
    if (value.rfind("LIST", 0) == 0) {
      h.list_dim = Trim(value.substr(4));
      AddList(h.references, file.parent_path(), lines, i + 1, truncated);
      return h;  // the list runs to the end of the file
    } else if (value.find('%') != std::string::npos) {
      AddPattern(h.references, file.parent_path(), value, &h.list_dim);
    } else {
      AddFile(h.references, file.parent_path(), value);
    }
  }
  h.line_count = i;
  if (!ended && truncated) {
    h.references.problem = fmt::format("a header longer than {} bytes", kMaxHeaderBytes);
  }
  return h;
}

}  // namespace cinevol::formats::nrrd
