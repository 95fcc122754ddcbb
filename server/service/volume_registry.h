// The volumes a server holds, by id. Operators preload any path or phantom
// (--volume); clients load only under the data roots (--data-root), where a
// path that climbs out with `..` or a symlink that leads out is refused, or
// upload a file that is checked exactly as a file on disk would be. A volume
// that a session leases cannot be unloaded.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "cinevol/v1/service.pb.h"
#include "core/volume.h"

namespace cinevol::service {

class VolumeRegistry;

// A session's or a still's hold on a volume: Unload refuses while one lives.
class VolumeLease {
 public:
  VolumeLease(VolumeRegistry* registry, std::string id, std::shared_ptr<const Volume> volume);
  ~VolumeLease();
  VolumeLease(const VolumeLease&) = delete;
  VolumeLease& operator=(const VolumeLease&) = delete;

  const std::string& id() const { return id_; }
  const std::shared_ptr<const Volume>& volume() const { return volume_; }

 private:
  VolumeRegistry* registry_;
  std::string id_;
  std::shared_ptr<const Volume> volume_;
};

class VolumeRegistry {
 public:
  VolumeRegistry(std::vector<std::filesystem::path> data_roots, std::uint64_t max_upload_bytes);
  ~VolumeRegistry();

  // The operator's volume: a phantom spec ("phantom:head?size=64"), a file or a
  // DICOM folder anywhere. Loading the same source again returns the first.
  v1::VolumeInfo AddFromSpec(const std::string& spec);
  // A client's request: a file or DICOM folder under a data root. Reads the
  // disk (seconds for a large series): call it off the gRPC threads.
  v1::VolumeInfo LoadFromDataRoot(const std::string& path, const std::string& series_uid);
  // A client's upload, written to `file` (in upload_dir()) by the service;
  // `file_name` is the name the client gave. The file is removed.
  v1::VolumeInfo AddUpload(const std::filesystem::path& file, const std::string& file_name);

  v1::VolumeInfo Describe(const std::string& id) const;
  std::vector<v1::VolumeInfo> List() const;
  // FAILED_PRECONDITION while leased, NOT_FOUND for an unknown id.
  void Unload(const std::string& id);
  std::shared_ptr<VolumeLease> Lease(const std::string& id);

  // `path` resolved inside a data root (relative paths against the first),
  // symlinks followed; PERMISSION_DENIED outside them, NOT_FOUND when absent.
  // `field` names the request field in messages.
  std::filesystem::path ResolveDataPath(const std::string& path, const std::string& field) const;

  const std::filesystem::path& upload_dir() const { return upload_dir_; }
  std::uint64_t max_upload_bytes() const { return max_upload_bytes_; }
  // The file extensions an upload may have.
  static bool IsUploadableName(const std::string& file_name);

 private:
  friend class VolumeLease;
  struct Entry {
    std::string source;  // canonical path (+ series) or phantom spec: loading it twice returns this entry
    std::shared_ptr<const Volume> volume;
    int leases = 0;
  };

  v1::VolumeInfo Add(const std::string& base_id, const std::string& source, Volume volume);
  v1::VolumeInfo InfoLocked(const std::string& id, const Entry& e) const;
  void Release(const std::string& id);

  std::vector<std::filesystem::path> data_roots_;  // canonical
  std::uint64_t max_upload_bytes_;
  std::filesystem::path upload_dir_;
  mutable std::mutex mu_;
  std::map<std::string, Entry> volumes_;
};

}  // namespace cinevol::service
