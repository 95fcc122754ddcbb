// The files a NIfTI or Analyze header's reader opens beside it.
#include "io/formats/nifti/references.h"

#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>

#include "io/file_checks.h"

namespace fs = std::filesystem;

namespace cinevol::formats::nifti {

bool IsPairName(const std::string& ending) {
  return ending == ".hdr" || ending == ".img" || ending == ".hdr.gz" || ending == ".img.gz";
}

formats::References PairReferences(const fs::path& file) {
  formats::References refs{"NIfTI/Analyze .hdr/.img pair", {}, ""};
  std::string base = file.filename().string();
  std::string lower = base;
  for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (lower.ends_with(".gz")) base.resize(base.size() - 3);
  base.resize(base.size() - std::min<std::size_t>(base.size(), 4));  // .hdr .img .nii .nia
  for (const char* ext : {".hdr", ".HDR", ".hdr.gz", ".HDR.gz", ".img", ".IMG", ".img.gz", ".IMG.gz", ".nii",
                          ".nii.gz"}) {
    const fs::path sibling = file.parent_path() / (base + ext);
    std::error_code ec;
    if (sibling != file && fs::exists(fs::symlink_status(sibling, ec))) refs.files.push_back(sibling);
  }
  return refs;
}

formats::References FindReferences(const fs::path& file) {
  const int fd = file_checks::OpenRegularFile(file);
  if (fd < 0) return {};
  gzFile f = gzdopen(fd, "rb");
  if (!f) {
    close(fd);
    return {};
  }
  char h[348] = {};
  const int n = gzread(f, h, sizeof h);
  gzclose(f);
  std::int32_t size = 0;
  std::memcpy(&size, h, sizeof size);
  const std::int32_t swapped = std::int32_t(__builtin_bswap32(std::uint32_t(size)));
  if (n >= 8 && (size == 540 || swapped == 540)) {
    return std::memcmp(h + 4, "n+2", 4) == 0 ? formats::References{} : PairReferences(file);
  }
  if (n >= 8 && (size == 348 || swapped == 348)) {
    return n == 348 && std::memcmp(h + 344, "n+1", 4) == 0 ? formats::References{} : PairReferences(file);
  }
  return {};
}

}  // namespace cinevol::formats::nifti
