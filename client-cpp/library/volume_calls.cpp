#include "volume_calls.h"

#include <fmt/format.h>

#include <fstream>
#include <iterator>
#include <stdexcept>

#include "server_pool.h"

namespace cinevol {

VolumeCalls::VolumeCalls(ServerPool& pool, const std::string& server)
    : pool_(pool), stub_(v1::VolumeService::NewStub(pool.Channel(server))) {}

std::vector<v1::VolumeInfo> VolumeCalls::List() {
  v1::ListVolumesResponse response;
  Check(stub_->ListVolumes(pool_.CallContext().get(), {}, &response));
  return {response.volumes().begin(), response.volumes().end()};
}

v1::VolumeInfo VolumeCalls::Load(const v1::LoadVolumeRequest& request) {
  v1::VolumeInfo info;
  Check(stub_->LoadVolume(pool_.CallContext().get(), request, &info));
  return info;
}

v1::VolumeInfo VolumeCalls::Upload(const std::filesystem::path& file, v1::UploadVolumeChunk::Header fields,
                                   std::size_t chunk_bytes) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open", file.string()));
  v1::VolumeInfo info;
  auto context = pool_.CallContext();
  auto writer = stub_->UploadVolume(context.get(), &info);
  v1::UploadVolumeChunk header;
  fields.set_file_name(file.filename().string());
  fields.set_size_bytes(std::filesystem::file_size(file));
  *header.mutable_header() = std::move(fields);
  bool open = writer->Write(header);
  std::string buffer(chunk_bytes, '\0');
  while (open && in) {
    in.read(buffer.data(), std::streamsize(buffer.size()));
    if (in.gcount() == 0) break;
    v1::UploadVolumeChunk chunk;
    chunk.set_data(buffer.data(), std::size_t(in.gcount()));
    open = writer->Write(chunk);
  }
  writer->WritesDone();
  Check(writer->Finish());
  return info;
}

v1::VolumeInfo VolumeCalls::LoadLabels(const std::string& volume_id, const std::string& path,
                                       const std::string& table_path) {
  v1::LoadLabelsRequest request;
  request.set_volume_id(volume_id);
  request.set_path(path);
  request.set_table_path(table_path);
  v1::VolumeInfo info;
  Check(stub_->LoadLabels(pool_.CallContext().get(), request, &info));
  return info;
}

v1::VolumeInfo VolumeCalls::UploadLabels(const std::string& volume_id, const std::filesystem::path& file,
                                         const std::filesystem::path& table) {
  v1::UploadVolumeChunk::Header header;
  header.set_labels_for(volume_id);
  if (!table.empty()) {
    std::ifstream in(table, std::ios::binary);
    if (!in) throw std::runtime_error(fmt::format("{}: cannot open", table.string()));
    header.set_label_table(std::string(std::istreambuf_iterator<char>(in), {}));
  }
  return Upload(file, header);
}

v1::VolumeInfo VolumeCalls::Describe(const std::string& volume_id) {
  v1::DescribeVolumeRequest request;
  request.set_volume_id(volume_id);
  v1::VolumeInfo info;
  Check(stub_->DescribeVolume(pool_.CallContext().get(), request, &info));
  return info;
}

void VolumeCalls::Unload(const std::string& volume_id) {
  v1::UnloadVolumeRequest request;
  request.set_volume_id(volume_id);
  v1::UnloadVolumeResponse response;
  Check(stub_->UnloadVolume(pool_.CallContext().get(), request, &response));
}

}  // namespace cinevol
