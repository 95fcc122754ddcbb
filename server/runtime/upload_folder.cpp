#include "runtime/upload_folder.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>
#include <string_view>

#include "core/error.h"

namespace fs = std::filesystem;

namespace cinevol::service {
namespace {

constexpr std::string_view kPrefix = "cinevol-uploads-";
constexpr std::string_view kNewPrefix = ".cinevol-uploads-new-";  // while being made: the sweep passes it by

// Opens a folder (never through a symlink) and takes its lock without waiting; -1 where it is held or not ours.
int OpenLocked(const fs::path& folder) {
  const int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) return -1;
  struct stat info {};
  if (::fstat(fd, &info) != 0 || info.st_uid != ::geteuid() || ::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// The folders of servers that ended without removing theirs: named as ours are, owned by us, and unlocked.
void RemoveAbandonedFolders(const fs::path& temporary) {
  std::error_code ec;
  for (fs::directory_iterator it(temporary, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->path().filename().string().rfind(kPrefix, 0) != 0) continue;
    const int fd = OpenLocked(it->path());
    if (fd < 0) continue;  // a running server's, or another user's
    std::error_code removed;
    const auto files = fs::remove_all(it->path(), removed);
    ::close(fd);
    if (!removed) spdlog::info("removed {} ({} files): left by a server that ended without removing it",
                               it->path().string(), files);
  }
}

}  // namespace

UploadFolder::UploadFolder() {
  const fs::path temporary = fs::temp_directory_path();
  RemoveAbandonedFolders(temporary);
  // Made under a name the sweep ignores, locked, then renamed: another server
  // starting at the same moment never sees it unlocked.
  std::string made = (temporary / fmt::format("{}XXXXXX", kNewPrefix)).string();
  if (::mkdtemp(made.data()) == nullptr) {
    throw InputError(fmt::format("cannot make a folder in {}: {}", temporary.string(), std::strerror(errno)));
  }
  lock_fd_ = OpenLocked(made);
  const std::string random = fs::path(made).filename().string().substr(kNewPrefix.size());
  path_ = temporary / fmt::format("{}{}-{}", kPrefix, ::getpid(), random);
  if (lock_fd_ < 0 || ::rename(made.c_str(), path_.c_str()) != 0) {
    const int error = errno;
    if (lock_fd_ >= 0) ::close(lock_fd_);
    ::rmdir(made.c_str());
    throw InputError(fmt::format("cannot make the upload folder in {}: {}", temporary.string(), std::strerror(error)));
  }
}

UploadFolder::~UploadFolder() {
  std::error_code ignored;
  fs::remove_all(path_, ignored);
  ::close(lock_fd_);
}

}  // namespace cinevol::service
