// VolumeRegistry: ids, leases and the data-root policy.
#include "runtime/volume_registry.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <functional>
#include <string_view>

#include "core/error.h"
#include "core/log_safe.h"
#include "io/dicom_seg.h"
#include "io/label_volume.h"
#include "io/reader_cage.h"
#include "io/table_finder.h"
#include "io/volume_loader.h"
#include "render/prepared_volume.h"
#include "runtime/errors.h"
#include "scene/presets.h"
#include "scene/volume_kind.h"

namespace fs = std::filesystem;

namespace cinevol::service {
namespace {

constexpr const char* kUploadExtensions[] = {".nii.gz", ".nii", ".nrrd.gz", ".nrrd", ".mha", ".vtk"};
constexpr const char* kVolumeExtensions[] = {".nii.gz", ".nii", ".nrrd.gz", ".nrrd", ".nhdr", ".mha", ".mhd", ".vtk"};

bool EndsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && std::equal(tail.rbegin(), tail.rend(), s.rbegin(), [](char a, char b) {
           return std::tolower(static_cast<unsigned char>(a)) == std::tolower(static_cast<unsigned char>(b));
         });
}

// The host memory a volume's phases hold together, phases alike counted once.
std::uint64_t PhasesBytes(const std::vector<std::shared_ptr<const Volume>>& phases) {
  std::uint64_t bytes = 0;
  for (std::size_t k = 0; k < phases.size(); ++k) {
    const auto before = phases.begin() + std::ptrdiff_t(k);
    if (std::find(phases.begin(), before, phases[k]) == before) bytes += phases[k]->MemoryBytes();
  }
  return bytes;
}

// A volume's voxels as bytes, as it holds them.
std::string_view VoxelBytes(const Volume& v) {
  if (v.storage() == VoxelStorage::kUInt16) {
    return {reinterpret_cast<const char*>(v.u16().data()), v.u16().size() * sizeof(std::uint16_t)};
  }
  return {reinterpret_cast<const char*>(v.f32().data()), v.f32().size() * sizeof(float)};
}

bool SameVoxels(const Volume& a, const Volume& b) {
  return a.storage() == b.storage() && a.stored_offset() == b.stored_offset() && VoxelBytes(a) == VoxelBytes(b);
}

// Removes an upload's file however its load ends.
struct RemoveWhenDone {
  const fs::path& file;
  ~RemoveWhenDone() {
    std::error_code ec;
    fs::remove(file, ec);
  }
};

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

// Host memory of a segmentation: its labels and what is known of each.
std::uint64_t LabelBytes(const LabelVolume* labels) {
  if (!labels) return 0;
  std::uint64_t bytes = labels->labels.size() * sizeof(std::uint16_t);
  for (const auto& [value, name] : labels->names) bytes += sizeof(value) + name.size() + 64;
  return bytes + labels->voxels.size() * 64;  // a map node each
}

// What fitting a segmentation to `image` holds: a label per image voxel.
std::uint64_t LabelBytesFor(const Volume& image) { return image.voxel_count() * sizeof(std::uint16_t); }

// The DICOM fields a reading view shows (never logged: they name a patient).
void SetIdentity(const VolumeMetadata& meta, v1::VolumeInfo& info) {
  const PatientIdentity& id = meta.identity;
  if (!(id.patient_name + id.patient_id + id.study_date + id.study_description + id.series_description).empty()) {
    v1::PatientIdentity* out = info.mutable_identity();
    out->set_patient_name(id.patient_name);
    out->set_patient_id(id.patient_id);
    out->set_study_date(id.study_date);
    out->set_study_description(id.study_description);
    out->set_series_description(id.series_description);
  }
  if (meta.stored_window) {
    info.mutable_stored_window()->set_center(float(meta.stored_window->center));
    info.mutable_stored_window()->set_width(float(meta.stored_window->width));
  }
}

// A retrieved series' download folder, removed however the call ends (the
// volume it held is read by then, or the call failed).
struct FolderRemovedOnExit {
  const fs::path& folder;
  ~FolderRemovedOnExit() {
    std::error_code ec;
    fs::remove_all(folder, ec);
  }
};

}  // namespace

std::string Mib(std::uint64_t bytes) { return fmt::format("{:.1f} MiB", double(bytes) / (1 << 20)); }

std::vector<std::shared_ptr<const Volume>> ShareAlikePhases(std::vector<Volume> phases) {
  std::vector<std::shared_ptr<const Volume>> out;
  std::vector<std::size_t> hashes;  // of each phase's voxels, so only a likely match is compared whole
  for (Volume& phase : phases) {
    const std::size_t hash = std::hash<std::string_view>{}(VoxelBytes(phase));
    std::shared_ptr<const Volume> alike;
    for (std::size_t k = 0; k < out.size() && !alike; ++k) {
      if (hashes[k] == hash && SameVoxels(*out[k], phase)) alike = out[k];
    }
    hashes.push_back(hash);
    out.push_back(alike ? alike : std::make_shared<const Volume>(std::move(phase)));
  }
  return out;
}

class VolumeRegistry::Reservation {
 public:
  Reservation(VolumeRegistry* registry, std::string owner, bool upload, std::string what)
      : registry_(registry), owner_(std::move(owner)), upload_(upload), what_(std::move(what)) {}
  ~Reservation() {
    std::lock_guard lock(registry_->mu_);
    ReleaseLocked();
  }
  Reservation(const Reservation&) = delete;
  Reservation& operator=(const Reservation&) = delete;

  // Reserves `bytes` more, or throws RESOURCE_EXHAUSTED naming the limit.
  void Add(std::uint64_t bytes) {
    std::lock_guard lock(registry_->mu_);
    registry_->CheckRoomLocked(bytes, owner_, upload_, what_);
    bytes_ += bytes;
    registry_->reserved_ += bytes;
    if (upload_) registry_->reserved_uploads_[owner_] += bytes;
  }

  // Gives the bytes back (mu_ held): the load ended, or its volume is added.
  void ReleaseLocked() {
    registry_->reserved_ -= bytes_;
    if (upload_ && (registry_->reserved_uploads_[owner_] -= bytes_) == 0) registry_->reserved_uploads_.erase(owner_);
    bytes_ = 0;
  }

 private:
  VolumeRegistry* registry_;
  std::string owner_;
  bool upload_;
  std::string what_;
  std::uint64_t bytes_ = 0;
};

VolumeLease::VolumeLease(VolumeRegistry* registry, std::string id, std::vector<std::shared_ptr<const Volume>> phases,
                         std::vector<double> seconds, std::shared_ptr<const LabelVolume> labels)
    : registry_(registry),
      id_(std::move(id)),
      phases_(std::move(phases)),
      seconds_(std::move(seconds)),
      labels_(std::move(labels)) {}

VolumeLease::~VolumeLease() { registry_->Release(id_); }

VolumeRegistry::VolumeRegistry(std::vector<fs::path> data_roots, VolumeLimits limits)
    : limits_(limits) {
  for (const fs::path& root : data_roots) {
    std::error_code ec;
    const fs::path canonical = fs::canonical(root, ec);
    if (ec || !fs::is_directory(canonical)) {
      throw InputError(fmt::format("--data-root {}: not a folder", root.string()));
    }
    data_roots_.push_back(canonical);
  }
}

bool VolumeRegistry::IsUploadableName(const std::string& file_name) {
  return std::any_of(std::begin(kUploadExtensions), std::end(kUploadExtensions),
                     [&](const char* ext) { return EndsWith(file_name, ext); });
}

fs::path VolumeRegistry::ResolveDataPath(const std::string& path, const std::string& field) const {
  if (data_roots_.empty()) {
    throw RpcError::PermissionDenied(
        fmt::format("{}: this server has no data root (--data-root): it loads nothing from its disk", field));
  }
  if (path.empty()) throw RpcError::InvalidArgument(fmt::format("{}: is empty", field));
  const fs::path requested = fs::path(path).is_absolute() ? fs::path(path) : data_roots_.front() / path;
  // First the path as written (`..` climbing out), then where its symlinks lead.
  const fs::path lexical = requested.lexically_normal();
  auto inside_a_root = [&](const fs::path& p) {
    return std::any_of(data_roots_.begin(), data_roots_.end(), [&](const fs::path& r) { return IsInside(p, r); });
  };
  const std::string outside = fmt::format("{}: '{}' is outside the server's data roots", field, path);
  if (!inside_a_root(lexical)) throw RpcError::PermissionDenied(outside);
  std::error_code ec;
  const fs::path canonical = fs::canonical(requested, ec);
  if (ec) throw RpcError::NotFound(fmt::format("{}: '{}' does not exist", field, path));
  if (!inside_a_root(canonical)) {
    throw RpcError::PermissionDenied(outside + " (a symlink leads out)");
  }
  // FIFOs, sockets and devices would block a reader or never end.
  const fs::file_type type = fs::status(canonical, ec).type();
  if (type != fs::file_type::regular && type != fs::file_type::directory) {
    throw RpcError::InvalidArgument(fmt::format("{}: '{}' is not a regular file or folder", field, path));
  }
  return canonical;
}

LoadPolicy VolumeRegistry::PolicyFor(const std::string& label, bool upload, const std::atomic<bool>* cancel,
                                     Reservation* reservation) {
  LoadPolicy policy;
  policy.references = upload ? LoadPolicy::References::kNone : LoadPolicy::References::kInsideRoots;
  policy.roots = data_roots_;
  policy.max_voxels = limits_.max_voxels;
  policy.label = label;
  policy.reader = limits_.reader;
  policy.cancel = cancel;
  if (reservation) policy.reserve = [reservation](std::uint64_t bytes) { reservation->Add(bytes); };
  return policy;
}

void VolumeRegistry::CheckRoomLocked(std::uint64_t bytes, const std::string& owner, bool upload,
                                     const std::string& what) const {
  // Held and being loaded: a load's memory counts from its header on.
  const std::uint64_t total = HeldBytesLocked() + reserved_;
  // The caller's own quota first: it says what the caller can do about it.
  if (upload) {
    std::uint64_t owners = 0;
    for (const auto& [id, e] : volumes_) {
      if (e.upload && e.owner == owner) owners += PhasesBytes(e.phases);
    }
    if (const auto it = reserved_uploads_.find(owner); it != reserved_uploads_.end()) owners += it->second;
    if (owners + bytes > limits_.max_upload_bytes_per_principal) {
      throw LimitExceeded("max-upload-memory-mb",
                          fmt::format("your uploads hold {}; this one needs {} more, over the limit of {} per user "
                                      "(--max-upload-memory-mb): unload one first",
                                      Mib(owners), Mib(bytes), Mib(limits_.max_upload_bytes_per_principal)));
    }
  }
  if (total + bytes > limits_.max_total_bytes) {
    throw LimitExceeded("max-volume-memory-mb",
                        fmt::format("{} needs {}; this server holds {} of volumes and allows {} "
                                    "(--max-volume-memory-mb)",
                                    what, Mib(bytes), Mib(total), Mib(limits_.max_total_bytes)));
  }
}

v1::VolumeInfo VolumeRegistry::AddFromSpec(const std::string& spec) {
  const v1::VolumeSource source = ParseVolumeSpec(spec);
  if (source.has_phantom()) {
    // Built in, without a table: no search (it would take a second of the server's start).
    return Add(spec, spec, spec, LoadVolumeSeries(source), "", false, nullptr, {nullptr, "a phantom: no table"});
  }
  const fs::path path = fs::absolute(spec).lexically_normal();
  LoadPolicy policy;
  policy.reader = limits_.reader;
  policy.resample_uneven = limits_.resample_uneven;
  VolumeSeries series = LoadVolumeSeries(source, {}, policy);
  FoundTable table = SearchTable(series.phases.front(), nullptr, nullptr);
  return Add(BaseIdOf(path), path.string(), spec, std::move(series), "", false, nullptr, std::move(table));
}

std::string ReadChoices::Suffix() const {
  return (orientation.empty() ? "" : "@" + orientation) + (resample_uneven ? "@even" : "");
}

v1::VolumeInfo VolumeRegistry::LoadFromDataRoot(const std::string& path, const std::string& series_uid,
                                                const ReadChoices& choices, const Principal& caller,
                                                const std::atomic<bool>* cancel) {
  const fs::path resolved = ResolveDataPath(path, "path");
  const std::string source = resolved.string() + (series_uid.empty() ? "" : "#" + series_uid) + choices.Suffix();
  // Answers name the path as this client wrote it, never where it resolved to.
  const auto as_written = [&](v1::VolumeInfo info) {
    info.set_source(path);
    return info;
  };
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, e] : volumes_) {
      if (e.source == source) return as_written(InfoLocked(id, e));
    }
  }
  v1::VolumeSource request;
  if (fs::is_directory(resolved)) {
    request.set_dicom_folder(resolved.string());
    request.set_series_uid(series_uid);
  } else {
    request.set_file(resolved.string());
  }
  request.set_orientation(choices.orientation);
  request.set_resample_uneven(choices.resample_uneven || limits_.resample_uneven);
  Reservation reservation(this, caller.name, false, "the volume");
  VolumeSeries series = LoadVolumeSeries(request, {}, PolicyFor("path '" + path + "'", false, cancel, &reservation));
  FoundTable table = SearchTable(series.phases.front(), &reservation, cancel);
  return as_written(
      Add(BaseIdOf(resolved), source, path, std::move(series), caller.name, false, &reservation, std::move(table)));
}

v1::VolumeInfo VolumeRegistry::AddUpload(const fs::path& file, const std::string& file_name,
                                         const std::string& orientation, const Principal& caller,
                                         const std::atomic<bool>* cancel) {
  const RemoveWhenDone remove{file};
  const std::string shown = "upload:" + file_name;
  Reservation reservation(this, caller.name, true, "the volume");
  v1::VolumeSource request;
  request.set_file(file.string());
  request.set_orientation(orientation);
  VolumeSeries series = LoadVolumeSeries(request, {}, PolicyFor(shown, true, cancel, &reservation));
  FoundTable table = SearchTable(series.phases.front(), &reservation, cancel);
  return Add(BaseIdOf(file_name), shown, shown, std::move(series), caller.name, true, &reservation, std::move(table));
}

v1::VolumeInfo VolumeRegistry::AddRetrievedSeries(const fs::path& folder, const std::string& source,
                                                  const ReadChoices& choices, const Principal& caller,
                                                  const std::atomic<bool>* cancel) {
  const FolderRemovedOnExit remove{folder};
  v1::VolumeSource request;
  request.set_dicom_folder(folder.string());
  request.set_orientation(choices.orientation);
  request.set_resample_uneven(choices.resample_uneven || limits_.resample_uneven);
  Reservation reservation(this, caller.name, true, "the series");
  VolumeSeries phases = LoadVolumeSeries(request, {}, PolicyFor(source, true, cancel, &reservation));
  FoundTable table = SearchTable(phases.phases.front(), &reservation, cancel);
  std::string series = source.substr(source.rfind('/') + 1);
  series = series.substr(0, series.find('@'));
  const std::string base_id = "pacs-" + series.substr(series.size() > 12 ? series.size() - 12 : 0);
  return Add(base_id, source, source, std::move(phases), caller.name, true, &reservation, std::move(table));
}

std::optional<v1::VolumeInfo> VolumeRegistry::FindHeld(const std::string& source, const Principal& caller) const {
  std::lock_guard lock(mu_);
  for (const auto& [id, e] : volumes_) {
    if (e.source == source && (e.owner == caller.name || !e.upload)) return InfoLocked(id, e);
  }
  return std::nullopt;
}

void VolumeRegistry::RequireRoom(std::uint64_t voxels, std::uint64_t bytes, const Principal& caller,
                                 const std::string& what) const {
  if (voxels > limits_.max_voxels) {
    throw LimitExceeded("max-volume-voxels",
                        fmt::format("{} has {} voxels; this server loads at most {} (--max-volume-voxels)", what,
                                    voxels, limits_.max_voxels));
  }
  std::lock_guard lock(mu_);
  CheckRoomLocked(bytes, caller.name, true, what);
}

VolumeRegistry::FoundTable VolumeRegistry::SearchTable(const Volume& volume, Reservation* reservation,
                                                       const std::atomic<bool>* cancel) {
  try {
    // The search's byte a voxel while it runs, and the labels marking what it finds.
    if (reservation) reservation->Add(TableSearchBytes(volume.voxel_count()) + LabelBytesFor(volume));
  } catch (const LimitExceeded& e) {
    return {nullptr, std::string("no table search: ") + e.what()};
  }
  TableSettings settings;
  settings.cancel = cancel;
  const TableMask table = FindTable(volume, settings);
  spdlog::debug("table search: {} ({:.2f} s)", table.note, table.seconds);
  if (!table.found()) return {nullptr, table.note};
  return {std::make_shared<const LabelVolume>(TableLabels(table)), table.note};
}

v1::VolumeInfo VolumeRegistry::Add(const std::string& base_id, const std::string& source, const std::string& shown,
                                   VolumeSeries series, const std::string& owner, bool upload, Reservation* reservation,
                                   FoundTable table) {
  std::shared_ptr<const LabelVolume> unused;  // a table that does not fit, freed outside the lock
  std::vector<std::shared_ptr<const Volume>> phases = ShareAlikePhases(std::move(series.phases));  // before the lock
  std::lock_guard lock(mu_);
  if (reservation) reservation->ReleaseLocked();  // the volume itself counts from here on
  if (!upload) {
    for (const auto& [id, e] : volumes_) {
      if (e.source == source) return InfoLocked(id, e);
    }
  }
  const std::uint64_t bytes = PhasesBytes(phases);
  CheckRoomLocked(bytes, owner, upload, "the volume");
  // The table's labels count like a segmentation; the volume goes in without them where they do not fit.
  if (table.labels) {
    try {
      CheckRoomLocked(bytes + LabelBytes(table.labels.get()), owner, false, "the table's labels");
    } catch (const LimitExceeded& e) {
      unused = std::move(table.labels);
      table.note = fmt::format("a table was found but not kept: {}", e.what());
    }
  }
  std::string id = base_id;
  for (int n = 2; volumes_.count(id); ++n) id = fmt::format("{}-{}", base_id, n);
  Entry& e = volumes_[id];
  e.source = source;
  e.shown = shown;
  e.phases = std::move(phases);
  e.volume = e.phases.front();
  e.phase_seconds = std::move(series.seconds);
  e.owner = owner;
  e.upload = upload;
  e.labels = std::move(table.labels);
  e.table_note = std::move(table.note);
  // The source is a path or a client's file name: patient data, and not for the info log.
  spdlog::info("volume {}: {}x{}x{}, {} phase{}, {} MiB", LogSafe(id), e.volume->dims().x, e.volume->dims().y,
               e.volume->dims().z, e.phases.size(), e.phases.size() == 1 ? "" : "s", bytes >> 20);
  return InfoLocked(id, e);
}

std::uint64_t VolumeRegistry::HeldBytesLocked() const {
  std::uint64_t total = 0;
  for (const auto& [id, e] : volumes_) total += PhasesBytes(e.phases) + LabelBytes(e.labels.get());
  return total;
}

std::shared_ptr<const Volume> VolumeRegistry::VolumeForLabels(const std::string& id, const Principal& caller,
                                                              std::shared_ptr<const LabelVolume>* held,
                                                              const std::string& field) const {
  std::lock_guard lock(mu_);
  const Entry& e = FindLocked(id, caller, field);
  if (!caller.is_operator && e.owner != caller.name) {
    throw RpcError::PermissionDenied(
        fmt::format("{}: volume '{}' was loaded by {}; only its owner or an operator may load its "
                    "segmentation",
                    field, id, e.owner.empty() ? "the operator" : "another user"));
  }
  *held = e.labels;
  return e.volume;
}

v1::VolumeInfo VolumeRegistry::LoadLabels(const std::string& id, const std::string& path, const std::string& table_path,
                                          const Principal& caller, const std::atomic<bool>* cancel) {
  std::shared_ptr<const LabelVolume> held;
  const std::shared_ptr<const Volume> image = VolumeForLabels(id, caller, &held);
  const fs::path labels = ResolveDataPath(path, "path");
  const fs::path table = table_path.empty() ? fs::path() : ResolveDataPath(table_path, "table_path");
  Reservation reservation(this, caller.name, false, "the segmentation");
  const std::string shown = "path '" + path + "'";
  LabelVolume loaded = LoadLabelFile(labels, *image, held.get(), shown, false, cancel, reservation);
  if (!table.empty()) {                // a SEG's own names stay where the table names no other
    for (auto& [value, name] : LoadLabelTable(table, "table_path '" + table_path + "'")) loaded.names[value] = name;
  }
  return AttachLabels(id, image, std::move(loaded), caller, &reservation);
}

LabelVolume VolumeRegistry::LoadLabelFile(const fs::path& file, const Volume& image, const LabelVolume* held,
                                          const std::string& shown, bool upload, const std::atomic<bool>* cancel,
                                          Reservation& reservation) {
  LabelVolume loaded;
  // A DICOM SEG is placed in the reader cage and its memory reserved there (of
  // a .dcm the service lets only a SEG's labels through).
  if (IsDicomSegmentation(file)) {
    loaded = LoadSegmentation(file, image, PolicyFor(shown, upload, cancel, &reservation));
  } else {
    Volume labels = LoadVolumeFile(file, PolicyFor(shown, upload, cancel, &reservation));
    FollowImageOrientation(labels, image);
    reservation.Add(LabelBytesFor(image));
    loaded = FitLabels(labels, image, shown);
  }
  if (held) CopyTable(*held, loaded);  // the table found when the volume loaded stays marked
  return loaded;
}

void VolumeRegistry::RequireLabelsAllowed(const std::string& id, const Principal& caller,
                                          const std::string& field) const {
  std::shared_ptr<const LabelVolume> held;
  VolumeForLabels(id, caller, &held, field);
}

v1::VolumeInfo VolumeRegistry::AddRetrievedLabels(const std::string& id, const fs::path& folder,
                                                  const std::string& source, const Principal& caller,
                                                  const std::atomic<bool>* cancel) {
  const FolderRemovedOnExit remove{folder};
  std::shared_ptr<const LabelVolume> held;
  const std::shared_ptr<const Volume> image = VolumeForLabels(id, caller, &held, "labels_for");
  Reservation reservation(this, caller.name, false, "the segmentation");
  LabelVolume loaded = LoadSegmentation(folder, *image, PolicyFor(source, true, cancel, &reservation));
  if (held) CopyTable(*held, loaded);
  return AttachLabels(id, image, std::move(loaded), caller, &reservation);
}

v1::VolumeInfo VolumeRegistry::AddUploadedLabels(const std::string& id, const fs::path& file,
                                                 const std::string& file_name, const std::string& table,
                                                 const Principal& caller, const std::atomic<bool>* cancel) {
  const RemoveWhenDone remove{file};
  std::shared_ptr<const LabelVolume> held;
  const std::shared_ptr<const Volume> image = VolumeForLabels(id, caller, &held);
  const std::string shown = "upload:" + file_name;
  Reservation reservation(this, caller.name, false, "the segmentation");
  LabelVolume loaded = LoadLabelFile(file, *image, held.get(), shown, true, cancel, reservation);
  for (auto& [value, name] : reader_cage::ReadLabelTableText(table, "header.label_table")) loaded.names[value] = name;
  return AttachLabels(id, image, std::move(loaded), caller, &reservation);
}

v1::VolumeInfo VolumeRegistry::AttachLabels(const std::string& id, const std::shared_ptr<const Volume>& image,
                                            LabelVolume labels, const Principal& caller, Reservation* reservation) {
  std::shared_ptr<const LabelVolume> last;  // freed outside the lock
  std::lock_guard lock(mu_);
  reservation->ReleaseLocked();         // the segmentation itself counts from here on
  FindLocked(id, caller, "volume_id");  // it may have gone while the file loaded
  Entry& e = volumes_.at(id);
  if (e.volume != image) {
    throw RpcError::Aborted(
        fmt::format("volume_id: volume '{}' was replaced while its segmentation loaded; load it again", id));
  }
  const std::uint64_t bytes = LabelBytes(&labels), replaced = LabelBytes(e.labels.get());
  CheckRoomLocked(bytes > replaced ? bytes - replaced : 0, e.owner, false, "the segmentation");
  last = std::move(e.labels);
  e.labels = std::make_shared<const LabelVolume>(std::move(labels));
  spdlog::info("volume {}: segmentation with {} labels", LogSafe(id), e.labels->voxels.size());
  return InfoLocked(id, e);
}

const VolumeRegistry::Entry& VolumeRegistry::FindLocked(const std::string& id, const Principal& caller,
                                                        const std::string& field) const {
  auto it = volumes_.find(id);
  if (it == volumes_.end()) throw RpcError::NotFound(fmt::format("{}: no volume '{}'", field, id));
  if (it->second.upload && !caller.is_operator && it->second.owner != caller.name) {
    throw RpcError::PermissionDenied(fmt::format("{}: volume '{}' was uploaded by another user", field, id));
  }
  return it->second;
}

v1::VolumeInfo VolumeRegistry::InfoLocked(const std::string& id, const Entry& e) const {
  const Volume& v = *e.volume;
  v1::VolumeInfo info;
  info.set_id(id);
  info.set_source(e.shown);
  info.set_modality(v.metadata().modality);
  info.set_value_unit(v.metadata().value_unit);
  info.mutable_dims()->set_x(v.dims().x);
  info.mutable_dims()->set_y(v.dims().y);
  info.mutable_dims()->set_z(v.dims().z);
  *info.mutable_spacing_mm() = ToProto(v.spacing_mm());
  info.set_min_value(v.min_value());
  info.set_max_value(v.max_value());
  info.set_memory_bytes(PhasesBytes(e.phases));
  info.set_phases(std::uint32_t(e.phases.size()));
  info.mutable_phase_seconds()->Add(e.phase_seconds.begin(), e.phase_seconds.end());
  info.set_suv_factor(v.metadata().suv_factor);
  info.set_suv_refused(v.metadata().suv_refused);
  info.set_sessions(e.leases);
  const VolumeKindJudgement kind = JudgeVolumeKind(v);
  info.set_kind(kind.kind);
  info.set_kind_reason(kind.reason);
  info.set_default_preset(DefaultPreset(kind.kind));
  const ValueHistogram& h = v.histogram();
  info.mutable_histogram()->set_min_value(h.min_value);
  info.mutable_histogram()->set_max_value(h.max_value);
  info.mutable_histogram()->mutable_counts()->Add(h.counts.begin(), h.counts.end());
  info.mutable_direction()->Add(v.metadata().direction.begin(), v.metadata().direction.end());
  const auto& origin = v.metadata().origin_mm;
  *info.mutable_origin_mm() = ToProto(Vec3f{float(origin[0]), float(origin[1]), float(origin[2])});
  if (e.labels && e.labels->segmentation) *info.mutable_labels() = ToLabelSet(*e.labels);
  info.mutable_notes()->Add(v.metadata().notes.begin(), v.metadata().notes.end());
  info.mutable_table()->set_voxels(e.labels ? e.labels->table_voxels : 0);
  info.mutable_table()->set_note(e.table_note);
  SetIdentity(v.metadata(), info);
  for (const VolumeCopyStatus& c : VolumeCache::Get().Copies()) {
    if (c.volume != e.volume.get()) continue;
    v1::VolumeCopy* copy = info.add_copies();
    copy->set_device(DeviceLabel(c.device));
    copy->set_bytes(c.bytes);
    copy->set_renderers(std::uint32_t(c.renderers));
  }
  return info;
}

v1::VolumeInfo VolumeRegistry::Describe(const std::string& id, const Principal& caller) const {
  std::lock_guard lock(mu_);
  return InfoLocked(id, FindLocked(id, caller, "volume_id"));
}

std::vector<v1::VolumeInfo> VolumeRegistry::List(const Principal& caller) const {
  std::lock_guard lock(mu_);
  std::vector<v1::VolumeInfo> list;
  for (const auto& [id, e] : volumes_) {
    if (!e.upload || caller.is_operator || e.owner == caller.name) {
      list.push_back(InfoLocked(id, e));
      list.back().clear_histogram();  // lists stay small
    }
  }
  return list;
}

void VolumeRegistry::Unload(const std::string& id, const Principal& caller) {
  std::vector<std::shared_ptr<const Volume>> last;  // freed outside the lock
  std::lock_guard lock(mu_);
  const Entry& e = FindLocked(id, caller, "volume_id");
  if (!caller.is_operator && e.owner != caller.name) {
    throw RpcError::PermissionDenied(
        fmt::format("volume_id: volume '{}' was loaded by {}; only its owner or an operator may unload it", id,
                    e.owner.empty() ? "the operator" : "another user"));
  }
  if (e.leases > 0) {
    throw RpcError::FailedPrecondition(
        fmt::format("volume '{}' is in use by {} session(s) or still(s); close them first", id, e.leases));
  }
  auto it = volumes_.find(id);
  last = std::move(it->second.phases);
  volumes_.erase(it);
  spdlog::info("volume {}: unloaded", LogSafe(id));
}

std::shared_ptr<VolumeLease> VolumeRegistry::Lease(const std::string& id, const Principal& caller) {
  std::lock_guard lock(mu_);
  FindLocked(id, caller, "volume_id");
  Entry& e = volumes_.at(id);
  ++e.leases;
  return std::make_shared<VolumeLease>(this, id, e.phases, e.phase_seconds, e.labels);
}

void VolumeRegistry::Release(const std::string& id) {
  std::lock_guard lock(mu_);
  auto it = volumes_.find(id);
  if (it != volumes_.end()) --it->second.leases;
}

}  // namespace cinevol::service
