// VolumeRegistry: ids, leases and the data-root policy.
#include "service/volume_registry.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>

#include "core/error.h"
#include "io/volume_loader.h"
#include "service/errors.h"

namespace fs = std::filesystem;

namespace cinevol::service {
namespace {

constexpr const char* kUploadExtensions[] = {".nii.gz", ".nii", ".nrrd", ".mha", ".vtk"};
constexpr const char* kVolumeExtensions[] = {".nii.gz", ".nii", ".nrrd", ".nhdr", ".mha", ".mhd", ".vtk"};

bool EndsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && std::equal(tail.rbegin(), tail.rend(), s.rbegin(), [](char a, char b) {
           return std::tolower(static_cast<unsigned char>(a)) == std::tolower(static_cast<unsigned char>(b));
         });
}

// A readable id from a file or folder name: its stem, in [A-Za-z0-9._-].
std::string BaseIdOf(const fs::path& path) {
  std::string name = path.filename().string();
  if (name.empty()) name = path.parent_path().filename().string();
  for (const char* ext : kVolumeExtensions) {
    if (EndsWith(name, ext)) {
      name.resize(name.size() - std::string(ext).size());
      break;
    }
  }
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '-' && c != '_') c = '_';
  }
  return name.empty() ? "volume" : name;
}

// Whether `path` lies in `root` (both canonical).
bool IsInside(const fs::path& path, const fs::path& root) {
  auto [root_end, path_it] = std::mismatch(root.begin(), root.end(), path.begin(), path.end());
  return root_end == root.end();
}

v1::Vec3 ToProto(Vec3f v) {
  v1::Vec3 p;
  p.set_x(v.x);
  p.set_y(v.y);
  p.set_z(v.z);
  return p;
}

}  // namespace

VolumeLease::VolumeLease(VolumeRegistry* registry, std::string id, std::shared_ptr<const Volume> volume)
    : registry_(registry), id_(std::move(id)), volume_(std::move(volume)) {}

VolumeLease::~VolumeLease() { registry_->Release(id_); }

VolumeRegistry::VolumeRegistry(std::vector<fs::path> data_roots, std::uint64_t max_upload_bytes)
    : max_upload_bytes_(max_upload_bytes),
      upload_dir_(fs::temp_directory_path() / fmt::format("cinevol-uploads-{}", ::getpid())) {
  for (const fs::path& root : data_roots) {
    std::error_code ec;
    const fs::path canonical = fs::canonical(root, ec);
    if (ec || !fs::is_directory(canonical)) {
      throw InputError(fmt::format("--data-root {}: not a folder", root.string()));
    }
    data_roots_.push_back(canonical);
  }
  fs::create_directories(upload_dir_);
  fs::permissions(upload_dir_, fs::perms::owner_all, fs::perm_options::replace);
}

VolumeRegistry::~VolumeRegistry() {
  std::error_code ec;
  fs::remove_all(upload_dir_, ec);
}

bool VolumeRegistry::IsUploadableName(const std::string& file_name) {
  return std::any_of(std::begin(kUploadExtensions), std::end(kUploadExtensions),
                     [&](const char* ext) { return EndsWith(file_name, ext); });
}

fs::path VolumeRegistry::ResolveDataPath(const std::string& path, const std::string& field) const {
  if (data_roots_.empty()) {
    throw RpcError(grpc::StatusCode::PERMISSION_DENIED,
                   fmt::format("{}: this server has no data root (--data-root): it loads nothing from its disk", field));
  }
  if (path.empty()) throw RpcError(grpc::StatusCode::INVALID_ARGUMENT, fmt::format("{}: is empty", field));
  const fs::path requested = fs::path(path).is_absolute() ? fs::path(path) : data_roots_.front() / path;
  // First the path as written (`..` climbing out), then where its symlinks lead.
  const fs::path lexical = requested.lexically_normal();
  auto inside_a_root = [&](const fs::path& p) {
    return std::any_of(data_roots_.begin(), data_roots_.end(), [&](const fs::path& r) { return IsInside(p, r); });
  };
  const std::string outside = fmt::format("{}: '{}' is outside the server's data roots", field, path);
  if (!inside_a_root(lexical)) throw RpcError(grpc::StatusCode::PERMISSION_DENIED, outside);
  std::error_code ec;
  const fs::path canonical = fs::canonical(requested, ec);
  if (ec) throw RpcError(grpc::StatusCode::NOT_FOUND, fmt::format("{}: '{}' does not exist", field, path));
  if (!inside_a_root(canonical)) {
    throw RpcError(grpc::StatusCode::PERMISSION_DENIED, outside + " (a symlink leads out)");
  }
  return canonical;
}

v1::VolumeInfo VolumeRegistry::AddFromSpec(const std::string& spec) {
  const v1::VolumeSource source = ParseVolumeSpec(spec);
  if (source.has_phantom()) return Add(spec, spec, LoadVolume(source));
  const fs::path path = fs::absolute(spec).lexically_normal();
  return Add(BaseIdOf(path), path.string(), LoadVolume(source));
}

v1::VolumeInfo VolumeRegistry::LoadFromDataRoot(const std::string& path, const std::string& series_uid) {
  const fs::path resolved = ResolveDataPath(path, "path");
  const std::string source = series_uid.empty() ? resolved.string() : resolved.string() + "#" + series_uid;
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, e] : volumes_) {
      if (e.source == source) return InfoLocked(id, e);
    }
  }
  v1::VolumeSource request;
  if (fs::is_directory(resolved)) {
    request.set_dicom_folder(resolved.string());
    request.set_series_uid(series_uid);
  } else {
    request.set_file(resolved.string());
  }
  return Add(BaseIdOf(resolved), source, LoadVolume(request));
}

v1::VolumeInfo VolumeRegistry::AddUpload(const fs::path& file, const std::string& file_name) {
  struct Remove {
    const fs::path& f;
    ~Remove() {
      std::error_code ec;
      fs::remove(f, ec);
    }
  } remove{file};
  Volume volume = LoadVolumeFile(file);
  return Add(BaseIdOf(file_name), "upload:" + file_name, std::move(volume));
}

v1::VolumeInfo VolumeRegistry::Add(const std::string& base_id, const std::string& source, Volume volume) {
  std::lock_guard lock(mu_);
  for (const auto& [id, e] : volumes_) {
    if (e.source == source && source.rfind("upload:", 0) != 0) return InfoLocked(id, e);
  }
  std::string id = base_id;
  for (int n = 2; volumes_.count(id); ++n) id = fmt::format("{}-{}", base_id, n);
  Entry& e = volumes_[id];
  e.source = source;
  e.volume = std::make_shared<const Volume>(std::move(volume));
  spdlog::info("volume {}: {}x{}x{} from {}", id, e.volume->dims().x, e.volume->dims().y, e.volume->dims().z, source);
  return InfoLocked(id, e);
}

v1::VolumeInfo VolumeRegistry::InfoLocked(const std::string& id, const Entry& e) const {
  const Volume& v = *e.volume;
  v1::VolumeInfo info;
  info.set_id(id);
  info.set_source(e.source);
  info.set_modality(v.metadata().modality);
  info.set_value_unit(v.metadata().value_unit);
  info.mutable_dims()->set_x(v.dims().x);
  info.mutable_dims()->set_y(v.dims().y);
  info.mutable_dims()->set_z(v.dims().z);
  *info.mutable_spacing_mm() = ToProto(v.spacing_mm());
  info.set_min_value(v.min_value());
  info.set_max_value(v.max_value());
  info.set_memory_bytes(v.MemoryBytes());
  info.set_sessions(e.leases);
  return info;
}

v1::VolumeInfo VolumeRegistry::Describe(const std::string& id) const {
  std::lock_guard lock(mu_);
  auto it = volumes_.find(id);
  if (it == volumes_.end()) throw RpcError(grpc::StatusCode::NOT_FOUND, fmt::format("no volume '{}'", id));
  return InfoLocked(id, it->second);
}

std::vector<v1::VolumeInfo> VolumeRegistry::List() const {
  std::lock_guard lock(mu_);
  std::vector<v1::VolumeInfo> list;
  for (const auto& [id, e] : volumes_) list.push_back(InfoLocked(id, e));
  return list;
}

void VolumeRegistry::Unload(const std::string& id) {
  std::shared_ptr<const Volume> last;  // freed outside the lock
  std::lock_guard lock(mu_);
  auto it = volumes_.find(id);
  if (it == volumes_.end()) throw RpcError(grpc::StatusCode::NOT_FOUND, fmt::format("no volume '{}'", id));
  if (it->second.leases > 0) {
    throw RpcError(grpc::StatusCode::FAILED_PRECONDITION,
                   fmt::format("volume '{}' is in use by {} session(s) or still(s); close them first", id,
                               it->second.leases));
  }
  last = std::move(it->second.volume);
  volumes_.erase(it);
  spdlog::info("volume {}: unloaded", id);
}

std::shared_ptr<VolumeLease> VolumeRegistry::Lease(const std::string& id) {
  std::lock_guard lock(mu_);
  auto it = volumes_.find(id);
  if (it == volumes_.end()) throw RpcError(grpc::StatusCode::NOT_FOUND, fmt::format("volume_id: no volume '{}'", id));
  ++it->second.leases;
  return std::make_shared<VolumeLease>(this, id, it->second.volume);
}

void VolumeRegistry::Release(const std::string& id) {
  std::lock_guard lock(mu_);
  auto it = volumes_.find(id);
  if (it != volumes_.end()) --it->second.leases;
}

}  // namespace cinevol::service
