// The volume calls, to one server of a ServerPool: what Client's volume
// methods send to its home server, and what failover sends to another to
// get a volume there as the client got it at home.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cinevol/v1/service.grpc.pb.h"

namespace cinevol {

class ServerPool;

class VolumeCalls {
 public:
  VolumeCalls(ServerPool& pool, const std::string& server);

  std::vector<v1::VolumeInfo> List();
  v1::VolumeInfo Load(const v1::LoadVolumeRequest& request);
  // Streams `file` after a header of `fields` (its name and size set here).
  v1::VolumeInfo Upload(const std::filesystem::path& file, v1::UploadVolumeChunk::Header fields,
                        std::size_t chunk_bytes = 1 << 20);
  v1::VolumeInfo LoadLabels(const std::string& volume_id, const std::string& path, const std::string& table_path);
  v1::VolumeInfo UploadLabels(const std::string& volume_id, const std::filesystem::path& file,
                              const std::filesystem::path& table);
  v1::VolumeInfo Describe(const std::string& volume_id);
  void Unload(const std::string& volume_id);

 private:
  ServerPool& pool_;
  std::unique_ptr<v1::VolumeService::Stub> stub_;
};

}  // namespace cinevol
