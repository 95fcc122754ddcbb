// The files of a DICOM folder that a load may read.
#include "io/formats/dicom/folder.h"

#include <algorithm>

#include <fmt/format.h>

#include "core/error.h"
#include "io/file_checks.h"

namespace fs = std::filesystem;

namespace cinevol::formats::dicom {
namespace {

// A folder with more files than this is not one patient's series.
constexpr std::size_t kMaxFolderFiles = 100000;

}  // namespace

std::vector<reader_cage::Input> FolderFiles(const fs::path& folder, const LoadPolicy& policy,
                                            const std::string& shown) {
  using R = LoadPolicy::References;
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) throw InputError(fmt::format("{}: not a folder", shown));
  file_checks::RequireInsideRoots(folder, policy, shown);
  const std::vector<fs::path> allowed = policy.references == R::kNone ? std::vector<fs::path>{fs::canonical(folder, ec)}
                                                                      : policy.roots;
  std::vector<reader_cage::Input> files;
  for (fs::recursive_directory_iterator it(folder, fs::directory_options::skip_permission_denied, ec), end;
       !ec && it != end; it.increment(ec)) {
    if (it->is_directory(ec) || !file_checks::IsRegularFile(it->path())) continue;
    if (policy.references != R::kAnywhere && !file_checks::IsInside(fs::canonical(it->path(), ec), allowed)) continue;
    if (files.size() == kMaxFolderFiles) {
      throw InputError(fmt::format("{}: more than {} files in the folder", shown, kMaxFolderFiles));
    }
    files.push_back({it->path(), it->path().lexically_relative(folder).string()});
  }
  if (ec) throw InputError(fmt::format("{}: cannot list the folder", shown));
  if (files.empty()) throw InputError(fmt::format("{}: no DICOM files found (0 files looked at)", shown));
  std::sort(files.begin(), files.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  return files;
}

}  // namespace cinevol::formats::dicom
