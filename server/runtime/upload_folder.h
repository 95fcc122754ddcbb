// The server's own folder in the temporary folder for what clients upload and
// what a PACS sends: private (0700), locked while the server runs, removed
// when it ends. A server that ended without removing it (killed, crashed)
// leaves it unlocked; the next server to start removes it, so uploads do not
// pile up in /tmp across crashes. The lock (flock) is the test, not the
// process id, which another pid namespace or a restarted container reuses.
#pragma once

#include <filesystem>

namespace cinevol::service {

class UploadFolder {
 public:
  // Removes the abandoned folders of servers that ended without cleaning up,
  // then makes and locks this server's own.
  UploadFolder();
  ~UploadFolder();
  UploadFolder(const UploadFolder&) = delete;
  UploadFolder& operator=(const UploadFolder&) = delete;

  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  int lock_fd_ = -1;  // the folder itself, open and flock'ed for the server's life
};

}  // namespace cinevol::service
