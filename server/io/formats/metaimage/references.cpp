// The files a MetaImage header's ElementDataFile names.
#include "io/formats/metaimage/references.h"

#include <vector>

#include <fmt/format.h>

#include "io/file_checks.h"
#include "io/formats/header_text.h"

namespace fs = std::filesystem;

namespace cinevol::formats::metaimage {

bool IsLocal(const std::string& value) { return value == "LOCAL" || value == "Local" || value == "local"; }

formats::References FindReferences(const fs::path& file, const std::string& shown) {
  const std::string head = file_checks::ReadHead(file, kMaxHeaderBytes + 1, shown);
  const bool truncated = head.size() > kMaxHeaderBytes;
  const std::vector<std::string> lines = Lines(head);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::size_t sep = lines[i].find_first_of("=:");
    if (sep == std::string::npos || NormalKey(lines[i].substr(0, sep)) != "elementdatafile") continue;
    const std::string value = Trim(lines[i].substr(sep + 1));
    if (IsLocal(value)) return {};
    formats::References refs{"ElementDataFile", {}, ""};
    if (value.rfind("LIST", 0) == 0) {
      AddList(refs, file.parent_path(), lines, i + 1, truncated);
    } else if (value.find('%') != std::string::npos) {
      AddPattern(refs, file.parent_path(), value, nullptr);
    } else {
      AddFile(refs, file.parent_path(), value);
    }
    return refs;
  }
  if (!truncated) return {};
  return {"", {}, fmt::format("a header longer than {} bytes", kMaxHeaderBytes)};
}

}  // namespace cinevol::formats::metaimage
