// The volumes a server holds, by id. Operators preload any path or phantom
// (--volume); clients load only under the data roots (--data-root), where a
// path that climbs out with `..` or a symlink that leads out is refused, or
// upload a self-contained file. A volume that a session leases cannot be
// unloaded.
//
// Who sees what: preloaded volumes and files from the data roots are shared
// (every caller sees and renders them); an upload is its uploader's alone.
// Only a volume's owner (whoever loaded or uploaded it; the operator for
// preloaded ones) or an operator may unload it. Memory is bounded: voxels per
// volume, all volumes together, and uploads per principal.
#pragma once

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <map>
#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "cinevol/v1/service.pb.h"
#include "core/labels.h"
#include "core/volume.h"
#include "io/volume_loader.h"
#include "runtime/principal.h"
#include "runtime/upload_folder.h"

namespace cinevol::service {

class VolumeRegistry;

// A session's or a still's hold on a volume: Unload refuses while one lives.
class VolumeLease {
 public:
  // `phases`: a time series' (the first is the volume), or the one volume;
  // `seconds`: each phase's time from the first, where the series says.
  VolumeLease(VolumeRegistry* registry, std::string id, std::vector<std::shared_ptr<const Volume>> phases,
              std::vector<double> seconds, std::shared_ptr<const LabelVolume> labels);
  ~VolumeLease();
  VolumeLease(const VolumeLease&) = delete;
  VolumeLease& operator=(const VolumeLease&) = delete;

  const std::string& id() const { return id_; }
  // The volume: a time series' first phase.
  const std::shared_ptr<const Volume>& volume() const { return phases_.front(); }
  // A time series' phases (one for a still volume), alike in grid; phase(k)
  // for k past the last is the last.
  int phases() const { return int(phases_.size()); }
  const std::shared_ptr<const Volume>& phase(int k) const {
    return phases_[std::size_t(std::clamp(k, 0, phases() - 1))];
  }
  const std::vector<double>& phase_seconds() const { return seconds_; }
  // Its labels when the lease began: the segmentation and the table marked
  // (LabelVolume::segmentation says whether there is a segmentation); null: neither.
  const std::shared_ptr<const LabelVolume>& labels() const { return labels_; }
  bool has_segmentation() const { return labels_ && labels_->segmentation; }

 private:
  VolumeRegistry* registry_;
  std::string id_;
  std::vector<std::shared_ptr<const Volume>> phases_;
  std::vector<double> seconds_;
  std::shared_ptr<const LabelVolume> labels_;
};

// How a caller asks for a volume to be read. A volume so read is another
// than the same source read as it is.
struct ReadChoices {
  std::string orientation;       // overrides the file's ("LPI"; docs/volumes-and-scenes.md)
  bool resample_uneven = false;  // a DICOM series' uneven slice gaps resampled onto an even grid, not refused
  // What the choices add to a source's key: "@LPI", "@even", or nothing.
  std::string Suffix() const;
};

// "12.3 MiB": memory in the limits' messages.
std::string Mib(std::uint64_t bytes);

// A series' phases as the registry holds them: phases whose voxels are alike
// (a still stretch of a dynamic series, a baseline repeated) share one
// Volume, so one host copy, one device copy (the volume cache's, by Volume)
// and one set of majorants; a switch between them is none
// (FramePipeline::SetPhase keeps its samples). Found by a hash of each
// phase's voxels, then compared whole.
std::vector<std::shared_ptr<const Volume>> ShareAlikePhases(std::vector<Volume> phases);

struct VolumeLimits {
  std::uint64_t max_upload_bytes = 2048ull << 20;        // one upload's file
  std::uint64_t max_voxels = 1ull << 30;                  // one volume
  std::uint64_t max_total_bytes = 32ull << 30;            // every volume held, host memory
  std::uint64_t max_upload_bytes_per_principal = 8ull << 30;  // voxel memory of one principal's uploads
  ReaderLimits reader;                                    // each load's reader child
  bool resample_uneven = false;  // --resample-uneven: every DICOM series' uneven gaps resampled, not refused
};

class VolumeRegistry {
 public:
  VolumeRegistry(std::vector<std::filesystem::path> data_roots, VolumeLimits limits);

  // The operator's volume: a phantom spec ("phantom:head?size=64"), a file or a
  // DICOM folder anywhere. Loading the same source again returns the first.
  v1::VolumeInfo AddFromSpec(const std::string& spec);
  // Loads below read files through the reader cage (io/reader_cage.h):
  // seconds for a large series, so call them off the gRPC threads. Memory is
  // reserved from the file's header before any voxel is read, against the
  // limits; raising `cancel` stops a load within a second.

  // A client's request: a file or DICOM folder under a data root, which may
  // name other files only inside the data roots.
  v1::VolumeInfo LoadFromDataRoot(const std::string& path, const std::string& series_uid, const ReadChoices& choices,
                                  const Principal& caller, const std::atomic<bool>* cancel = nullptr);
  // A client's upload, written to `file` (in upload_dir()) by the service;
  // `file_name` is the name the client gave. It may name no other file. The
  // file is removed.
  v1::VolumeInfo AddUpload(const std::filesystem::path& file, const std::string& file_name,
                           const std::string& orientation, const Principal& caller,
                           const std::atomic<bool>* cancel = nullptr);

  // A series retrieved from a PACS into `folder` (in upload_dir(); removed):
  // read as a DICOM folder, held for `caller` alone like an upload, its
  // source `source` ("pacs:NAME/STUDY_UID/SERIES_UID" and the choices' suffix).
  v1::VolumeInfo AddRetrievedSeries(const std::filesystem::path& folder, const std::string& source,
                                    const ReadChoices& choices, const Principal& caller,
                                    const std::atomic<bool>* cancel = nullptr);
  // The volume `caller` already holds from `source`, if any.
  std::optional<v1::VolumeInfo> FindHeld(const std::string& source, const Principal& caller) const;
  // Throws (LimitExceeded, naming the flag) unless a volume of `voxels` and
  // `bytes` more would fit the limits of `caller`'s private volumes; `what`
  // names it. Nothing is reserved: the load reserves again from the header.
  void RequireRoom(std::uint64_t voxels, std::uint64_t bytes, const Principal& caller, const std::string& what) const;

  // A segmentation for volume `id`: a label volume and optionally its table,
  // both under the data roots; it replaces any earlier one, for sessions
  // created afterwards. Only the volume's owner or an operator may.
  v1::VolumeInfo LoadLabels(const std::string& id, const std::string& path, const std::string& table_path,
                            const Principal& caller, const std::atomic<bool>* cancel = nullptr);
  // A DICOM SEG retrieved from a PACS into `folder` (in upload_dir();
  // removed) as volume `id`'s segmentation, as LoadLabels loads a SEG file;
  // `source` ("pacs:NAME/STUDY_UID/SERIES_UID") names it.
  v1::VolumeInfo AddRetrievedLabels(const std::string& id, const std::filesystem::path& folder,
                                    const std::string& source, const Principal& caller,
                                    const std::atomic<bool>* cancel = nullptr);
  // Throws unless `caller` may load a segmentation for volume `id`
  // (NOT_FOUND, PERMISSION_DENIED); messages name the request's `field`.
  void RequireLabelsAllowed(const std::string& id, const Principal& caller, const std::string& field) const;
  // The same from an upload written to `file` (removed), with the table's text.
  v1::VolumeInfo AddUploadedLabels(const std::string& id, const std::filesystem::path& file,
                                   const std::string& file_name, const std::string& table, const Principal& caller,
                                   const std::atomic<bool>* cancel = nullptr);

  // NOT_FOUND for an unknown id; PERMISSION_DENIED for another's upload.
  v1::VolumeInfo Describe(const std::string& id, const Principal& caller) const;
  // The volumes `caller` may render.
  std::vector<v1::VolumeInfo> List(const Principal& caller) const;
  // FAILED_PRECONDITION while leased; PERMISSION_DENIED unless the caller
  // owns it or is an operator.
  void Unload(const std::string& id, const Principal& caller);
  std::shared_ptr<VolumeLease> Lease(const std::string& id, const Principal& caller);

  // `path` resolved inside a data root (relative paths against the first),
  // symlinks followed; PERMISSION_DENIED outside them, NOT_FOUND when absent.
  // `field` names the request field in messages.
  std::filesystem::path ResolveDataPath(const std::string& path, const std::string& field) const;

  const std::filesystem::path& upload_dir() const { return upload_folder_.path(); }
  const VolumeLimits& limits() const { return limits_; }
  // The file extensions an upload may have.
  static bool IsUploadableName(const std::string& file_name);

 private:
  friend class VolumeLease;
  // Memory reserved for one load under way: counted with what is held until
  // the volume is added or the load ends.
  class Reservation;

  struct Entry {
    std::string source;  // canonical path (+ series) or phantom spec: loading it twice returns this entry
    std::string shown;   // what answers call it: the path as its loader wrote it, or "upload:NAME"
    std::shared_ptr<const Volume> volume;  // a time series' first phase
    std::vector<std::shared_ptr<const Volume>> phases;  // every phase, `volume` first; one for a still volume
    std::vector<double> phase_seconds;                  // from the first, where the input said; else empty
    // Its segmentation, when one is loaded, with the table marked where one
    // was found; or labels marking the table alone (LabelVolume::segmentation false).
    std::shared_ptr<const LabelVolume> labels;
    std::string table_note;  // what the table search found when it loaded
    std::string owner;   // principal name; "" for the operator's preloaded volumes
    bool upload = false; // private to its owner
    int leases = 0;
  };

  // The table search's result for a volume being added.
  struct FoundTable {
    std::shared_ptr<const LabelVolume> labels;  // marking the table; null when none was found
    std::string note;
  };
  // Searches `volume` for a table (io/table_finder.h) under `reservation`:
  // skipped, said so in the note, where its memory does not fit.
  FoundTable SearchTable(const Volume& volume, Reservation* reservation, const std::atomic<bool>* cancel);
  // `series`: a time series' phases, or one volume.
  v1::VolumeInfo Add(const std::string& base_id, const std::string& source, const std::string& shown,
                     VolumeSeries series, const std::string& owner, bool upload, Reservation* reservation = nullptr,
                     FoundTable table = {});
  // Throws RESOURCE_EXHAUSTED unless `bytes` more fit the limits (an
  // upload's also its owner's); `what` names it in the message.
  void CheckRoomLocked(std::uint64_t bytes, const std::string& owner, bool upload, const std::string& what) const;
  // The entry `caller` may use, or throws NOT_FOUND / PERMISSION_DENIED.
  const Entry& FindLocked(const std::string& id, const Principal& caller, const std::string& field) const;
  v1::VolumeInfo InfoLocked(const std::string& id, const Entry& e) const;
  // The volume `id` for attaching labels: its owner's or an operator's; `held`: the labels it holds now.
  std::shared_ptr<const Volume> VolumeForLabels(const std::string& id, const Principal& caller,
                                                std::shared_ptr<const LabelVolume>* held,
                                                const std::string& field = "volume_id") const;
  // Holds `labels`, fitted to `image`, for volume `id` if that is still `image`.
  v1::VolumeInfo AttachLabels(const std::string& id, const std::shared_ptr<const Volume>& image, LabelVolume labels,
                              const Principal& caller, Reservation* reservation);
  // A label file for `image`: a DICOM SEG, or a label volume fitted to it
  // (its copy on `image`'s grid reserved first); `held`'s table stays marked.
  LabelVolume LoadLabelFile(const std::filesystem::path& file, const Volume& image, const LabelVolume* held,
                            const std::string& shown, bool upload, const std::atomic<bool>* cancel,
                            Reservation& reservation);
  std::uint64_t HeldBytesLocked() const;
  LoadPolicy PolicyFor(const std::string& label, bool upload, const std::atomic<bool>* cancel = nullptr,
                       Reservation* reservation = nullptr);
  void Release(const std::string& id);

  std::vector<std::filesystem::path> data_roots_;  // canonical
  VolumeLimits limits_;
  UploadFolder upload_folder_;
  mutable std::mutex mu_;
  std::map<std::string, Entry> volumes_;
  std::uint64_t reserved_ = 0;                         // loads under way, together
  std::map<std::string, std::uint64_t> reserved_uploads_;  // uploads under way, by owner
};

}  // namespace cinevol::service
