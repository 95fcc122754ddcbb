// The three services' methods.
#include "service/services.h"

#include <fmt/format.h>

#include <fstream>
#include <mutex>
#include <optional>

#include "core/log_safe.h"
#include "io/label_volume.h"
#include "io/volume_loader.h"
#include "runtime/errors.h"
#include "runtime/measurement_store.h"
#include "runtime/metrics.h"
#include "runtime/presentation_store.h"
#include "runtime/series_load.h"
#include "service/session_stream.h"

namespace cinevol::service {
namespace {

// Answers a unary call at once, on the gRPC thread, with what `f` returns or
// throws: only for work that does not grow with a volume (else PooledReactor).
template <class F>
grpc::ServerUnaryReactor* Answer(ServiceCore* core, grpc::CallbackServerContext* context, F&& f) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(Guarded([&] { f(core->Authenticate(*context)); }));
  return reactor;
}

// A unary call answered from a pool, never on a gRPC thread: for work that
// grows with a volume or waits on a peer. The reactor finishes from the pool,
// in the caller's queue there (pools take turns between callers). `stop`, which
// the work checks between its steps, is raised when the caller goes away
// (answered CANCELLED) or when the call has taken --max-call-seconds since it
// came, queued or running (DEADLINE_EXCEEDED): no call holds a worker for long.
class PooledReactor final : public grpc::ServerUnaryReactor {
 public:
  using Work = std::function<void(const Principal& caller, const std::atomic<bool>& stop)>;

  PooledReactor(grpc::CallbackServerContext* context, ServiceCore* core, TaskPool& pool, const char* what, Work work,
                const std::string& group = {})
      : core_(core), what_(what) {
    const grpc::Status status = Guarded([&] {
      const Principal caller = core->Authenticate(*context);
      core->RequireServing();
      watch_ = core->calls().Watch(context, Seconds(core->options().call_seconds), &stop_);
      const bool queued = pool.Submit(
          [this, caller, work = std::move(work)] {
            grpc::Status s = Stopped();
            if (s.ok()) s = Guarded([&] { work(caller, stop_); });
            if (!s.ok() && stop_) s = Stopped();  // the work's own Cancelled, said as why it stopped
            // Nothing of `this` is touched after Finish: OnDone may delete it at once.
            Finish(s);
          },
          caller.name, group);
      if (!queued) throw RpcError::Unavailable("the server is shutting down");
    });
    if (!status.ok()) Finish(status);
  }
  void OnCancel() override {
    caller_gone_ = true;
    stop_ = true;
  }
  void OnDone() override {
    if (watch_) core_->calls().Forget(watch_);
    delete this;
  }

 private:
  grpc::Status Stopped() const {
    if (caller_gone_) return RpcError::Cancelled("the caller went away").status();
    if (!stop_) return grpc::Status::OK;
    return RpcError::DeadlineExceeded(fmt::format("{} took longer than this server's {} s a call (--max-call-seconds)",
                                                  what_, core_->options().call_seconds))
        .status();
  }

  ServiceCore* core_;
  const char* what_;
  CallWatch::Id watch_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<bool> caller_gone_{false};
};

// An upload: chunks go straight to a private file (memory stays bounded),
// which is loaded on the loader pool once the client has sent everything.
// It holds one of the caller's upload slots, and ends when the client stays
// silent for --upload-idle-seconds.
class UploadReactor final : public grpc::ServerReadReactor<v1::UploadVolumeChunk> {
 public:
  UploadReactor(grpc::CallbackServerContext* context, ServiceCore* core, v1::VolumeInfo* response)
      : core_(core), response_(response) {
    const grpc::Status status = Guarded([&] {
      caller_ = core_->Authenticate(*context);
      slot_ = core_->BeginLoad(caller_);
    });
    if (!status.ok()) {
      Fail(status);
      return;
    }
    watch_ = core_->calls().Watch(context, Patience());
    StartRead(&chunk_);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {
      Complete();
      return;
    }
    core_->calls().Touch(watch_, Patience());
    const grpc::Status status = Guarded([&] { Take(chunk_); });
    if (!status.ok()) {
      Fail(status);
      return;
    }
    StartRead(&chunk_);
  }

  // The client gave up: a load under way stops (its reader is killed).
  void OnCancel() override {
    if (slot_) slot_->cancel = true;
  }

  void OnDone() override {
    core_->calls().Forget(watch_);
    std::error_code ec;
    if (!path_.empty() && !loading_) std::filesystem::remove(path_, ec);
    delete this;
  }

 private:
  CallWatch::Clock::duration Patience() const { return Seconds(core_->options().upload_idle_seconds); }

  void Take(const v1::UploadVolumeChunk& chunk) {
    if (chunk.has_header()) {
      if (file_.is_open()) throw InputError("header: sent twice; send it once, first");
      const auto& h = chunk.header();
      const bool seg = !h.labels_for().empty() && Extension(h.file_name()) == ".dcm";  // a DICOM SEG's labels
      if ((!VolumeRegistry::IsUploadableName(h.file_name()) && !seg) || h.file_name().size() > 255) {
        throw InputError(
            fmt::format("header.file_name: '{}' is not .nii, .nii.gz, .nrrd, .nrrd.gz, .mha or .vtk (formats "
                        "whose voxels travel in the one file), nor a DICOM SEG (.dcm) with header.labels_for, up "
                        "to 255 characters",
                        LogSafe(h.file_name(), 64)));
      }
      CheckSize(h.size_bytes(), "header.size_bytes");
      if (h.label_table().size() > kMaxLabelTableBytes) {
        throw InputError(
            fmt::format("header.label_table: {} bytes; at most {}", h.label_table().size(), kMaxLabelTableBytes));
      }
      if (!h.label_table().empty() && h.labels_for().empty()) {
        throw InputError("header.label_table: only with header.labels_for (a label volume's names)");
      }
      if (!h.orientation().empty()) ParseOrientation(h.orientation(), "header.orientation");  // before any data
      labels_for_ = h.labels_for();
      label_table_ = h.label_table();
      orientation_ = h.orientation();
      expected_ = h.size_bytes();
      // Only the name's last part, control characters escaped: it reaches messages and the log.
      name_ = LogSafe(std::filesystem::path(h.file_name()).filename().string());
      static std::atomic<int> counter{0};
      // The file on disk is named by the server alone; the extension tells the loader the format.
      path_ = core_->volumes().upload_dir() / fmt::format("{}{}", counter++, Extension(h.file_name()));
      file_.open(path_, std::ios::binary);
      if (!file_) throw std::runtime_error("cannot create the upload file " + path_.string());
      return;
    }
    if (!file_.is_open()) throw InputError("header: the first message must be the header");
    received_ += chunk.data().size();
    if (received_ > expected_) {
      throw InputError(fmt::format("data: more bytes than header.size_bytes ({})", expected_));
    }
    file_.write(chunk.data().data(), std::streamsize(chunk.data().size()));
    if (!file_) throw ResourceExhausted("cannot write the upload to the server's disk");
  }

  // The name's format extension, lower case (".nii.gz", ".nrrd", ...).
  static std::string Extension(const std::string& file_name) {
    std::string lower = file_name;
    for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
    for (const char* gz : {".nii.gz", ".nrrd.gz"}) {
      if (lower.ends_with(gz)) return gz;
    }
    return std::filesystem::path(lower).extension().string();
  }

  void CheckSize(std::uint64_t size, const char* field) const {
    const std::uint64_t limit = core_->volumes().limits().max_upload_bytes;
    if (size > limit) {
      throw LimitExceeded("max-upload-mb",
                          fmt::format("{}: {} bytes is over this server's upload limit of {} bytes (--max-upload-mb)",
                                      field, size, limit));
    }
    if (size == 0) throw InputError(fmt::format("{}: is 0", field));
  }

  void Complete() {
    if (!file_.is_open()) {
      Fail(RpcError::InvalidArgument("header: no header was sent").status());
      return;
    }
    file_.close();
    if (received_ != expected_) {
      Fail(RpcError::InvalidArgument(
               fmt::format("data: {} bytes received, header.size_bytes said {}", received_, expected_))
               .status());
      return;
    }
    loading_ = true;  // the loader removes the file
    // Everything came: the idle watch ends (a load has its reader's limits).
    core_->calls().Forget(watch_);
    const bool queued = core_->loader().Submit(
        [this] {
          const grpc::Status status = Guarded([&] {
            core_->RequireServing();
            *response_ = labels_for_.empty()
                             ? core_->volumes().AddUpload(path_, name_, orientation_, caller_, &slot_->cancel)
                             : core_->volumes().AddUploadedLabels(labels_for_, path_, name_, label_table_, caller_,
                                                                  &slot_->cancel);
          });
          ServerMetrics().Upload(status.ok());
          slot_->Release();
          Finish(status);
        },
        caller_.name);
    if (!queued) {
      loading_ = false;  // OnDone removes the file
      Fail(RpcError::Unavailable("the server is shutting down").status());
    }
  }

  void Fail(const grpc::Status& status) {
    ServerMetrics().Upload(false);
    file_.close();
    Finish(status);
  }

  ServiceCore* core_;
  v1::VolumeInfo* response_;
  Principal caller_;
  std::shared_ptr<LoadSlot> slot_;  // one of the caller's upload slots
  CallWatch::Id watch_ = 0;
  v1::UploadVolumeChunk chunk_;
  std::ofstream file_;
  std::filesystem::path path_;
  std::string name_;
  std::string labels_for_, label_table_;  // a segmentation's upload: its volume and label table
  std::string orientation_;               // overrides the file's ("LPI")
  std::uint64_t expected_ = 0, received_ = 0;
  bool loading_ = false;
};

// A still: the job learns through `cancel_` that its caller went away.
class SnapshotReactor final : public grpc::ServerUnaryReactor {
 public:
  SnapshotReactor(grpc::CallbackServerContext* context, ServiceCore* core, const v1::SnapshotRequest* request,
                  v1::SnapshotResponse* response) {
    const grpc::Status status = Guarded([&] {
      ServiceCore::SnapshotCallbacks callbacks;
      callbacks.done = [this, response](grpc::Status s, v1::SnapshotResponse r) {
        *response = std::move(r);
        Finish(s);
      };
      core->Snapshot(*request, core->Authenticate(*context), cancel_, std::move(callbacks));
    });
    if (!status.ok()) Finish(status);
  }
  void OnCancel() override { *cancel_ = true; }
  void OnDone() override { delete this; }

 private:
  std::shared_ptr<std::atomic<bool>> cancel_ = std::make_shared<std::atomic<bool>>(false);
};

// A call's progress, then its answer, on a server stream (a still, a series
// from a PACS). One write in flight: a newer progress replaces one waiting,
// and the answer (or the error) goes last. The work's callbacks end with
// Complete, and Finish is called only after it, so none of them outlives the
// reactor; a client gone or a failed write raises `cancel()`, which the work
// sees within a step. `progress_field` and `answer_field` are Update's
// mutable accessors of its two cases.
template <class Update, class Progress, class Answer, Progress* (Update::*progress_field)(),
          Answer* (Update::*answer_field)()>
class ProgressStreamReactor final : public grpc::ServerWriteReactor<Update> {
 public:
  // `cancel`: the flag the work watches; null: one of its own.
  explicit ProgressStreamReactor(std::shared_ptr<std::atomic<bool>> cancel = nullptr)
      : cancel_(cancel ? std::move(cancel) : std::make_shared<std::atomic<bool>>(false)) {}

  const std::shared_ptr<std::atomic<bool>>& cancel() const { return cancel_; }

  void Offer(const Progress& progress) {
    std::lock_guard lock(mu_);
    pending_ = progress;
    WriteNextLocked();
  }

  void Complete(grpc::Status status, Answer answer) {
    std::lock_guard lock(mu_);
    status_ = std::move(status);
    if (status_->ok()) *(last_.*answer_field)() = std::move(answer);
    pending_.reset();  // the answer makes older news moot
    WriteNextLocked();
  }

  void OnWriteDone(bool ok) override {
    std::lock_guard lock(mu_);
    writing_ = false;
    if (!ok) *cancel_ = true;  // the client is gone: stop the work; Complete still finishes
    WriteNextLocked();
  }
  void OnCancel() override { *cancel_ = true; }
  void OnDone() override { delete this; }

 private:
  void WriteNextLocked() {
    if (writing_ || finished_) return;
    if (pending_) {
      *(out_.*progress_field)() = *std::exchange(pending_, std::nullopt);
      writing_ = true;
      this->StartWrite(&out_);
    } else if (status_) {
      finished_ = true;
      if (status_->ok() && !*cancel_) {
        this->StartWriteAndFinish(&last_, grpc::WriteOptions(), *status_);
      } else {
        this->Finish(status_->ok() ? RpcError::Cancelled("the caller went away").status() : *status_);
      }
    }
  }

  std::shared_ptr<std::atomic<bool>> cancel_;
  std::mutex mu_;
  bool writing_ = false, finished_ = false;
  std::optional<Progress> pending_;     // the newest progress not yet written
  std::optional<grpc::Status> status_;  // set by Complete: write the answer, or finish with the error
  Update out_, last_;
};

using SnapshotStreamReactor =
    ProgressStreamReactor<v1::SnapshotUpdate, v1::SnapshotProgress, v1::SnapshotResponse,
                          &v1::SnapshotUpdate::mutable_progress, &v1::SnapshotUpdate::mutable_still>;
using MovieStreamReactor = ProgressStreamReactor<v1::MovieUpdate, v1::MovieProgress, v1::Movie,
                                                 &v1::MovieUpdate::mutable_progress, &v1::MovieUpdate::mutable_movie>;
using SeriesStreamReactor =
    ProgressStreamReactor<v1::LoadSeriesUpdate, v1::LoadSeriesProgress, v1::VolumeInfo,
                          &v1::LoadSeriesUpdate::mutable_progress, &v1::LoadSeriesUpdate::mutable_volume>;

}  // namespace

grpc::ServerUnaryReactor* VolumeServiceImpl::ListVolumes(grpc::CallbackServerContext* context,
                                                         const v1::ListVolumesRequest*,
                                                         v1::ListVolumesResponse* response) {
  return Answer(core_, context, [&](const Principal& caller) {
    for (v1::VolumeInfo& v : core_->volumes().List(caller)) *response->add_volumes() = std::move(v);
  });
}

grpc::ServerUnaryReactor* VolumeServiceImpl::LoadVolume(grpc::CallbackServerContext* context,
                                                        const v1::LoadVolumeRequest* request,
                                                        v1::VolumeInfo* response) {
  return LoadFromDisk(context, request->path(), [this, request, response](const Principal& caller, LoadSlot& slot) {
    *response =
        core_->volumes().LoadFromDataRoot(request->path(), request->series_uid(),
                                          {request->orientation(), request->resample_uneven()}, caller, &slot.cancel);
  });
}

grpc::ServerUnaryReactor* VolumeServiceImpl::LoadLabels(grpc::CallbackServerContext* context,
                                                        const v1::LoadLabelsRequest* request,
                                                        v1::VolumeInfo* response) {
  return LoadFromDisk(context, request->path(), [this, request, response](const Principal& caller, LoadSlot& slot) {
    *response =
        core_->volumes().LoadLabels(request->volume_id(), request->path(), request->table_path(), caller, &slot.cancel);
  });
}

namespace {

// A load from the disk: run on the loader pool, stopped (its reader killed)
// when the caller goes away.
class LoadReactor final : public grpc::ServerUnaryReactor {
 public:
  void OnCancel() override {
    if (auto slot = slot_.lock()) slot->cancel = true;
  }
  void OnDone() override { delete this; }
  void Hold(const std::shared_ptr<LoadSlot>& slot) { slot_ = slot; }

 private:
  std::weak_ptr<LoadSlot> slot_;
};

}  // namespace

grpc::ServerUnaryReactor* VolumeServiceImpl::LoadFromDisk(grpc::CallbackServerContext* context, const std::string& path,
                                                          std::function<void(const Principal&, LoadSlot&)> load) {
  auto* reactor = new LoadReactor;
  const grpc::Status status = Guarded([&] {
    const Principal caller = core_->Authenticate(*context);
    core_->RequireServing();
    // Refuse paths outside the data roots at once; read the disk on the loader pool.
    core_->volumes().ResolveDataPath(path, "path");
    // The load holds one of the caller's slots: a client cannot queue loads without end.
    std::shared_ptr<LoadSlot> slot = core_->BeginLoad(caller);
    reactor->Hold(slot);
    const bool queued = core_->loader().Submit(
        [this, reactor, load = std::move(load), caller, slot] {
          const grpc::Status status = Guarded([&] {
            core_->RequireServing();
            load(caller, *slot);
          });
          slot->Release();
          reactor->Finish(status);
        },
        caller.name);
    if (!queued) {
      slot->Release();
      throw RpcError::Unavailable("the server is shutting down");
    }
  });
  if (!status.ok()) reactor->Finish(status);
  return reactor;
}

grpc::ServerReadReactor<v1::UploadVolumeChunk>* VolumeServiceImpl::UploadVolume(grpc::CallbackServerContext* context,
                                                                                v1::VolumeInfo* response) {
  return new UploadReactor(context, core_, response);
}

grpc::ServerUnaryReactor* VolumeServiceImpl::DescribeVolume(grpc::CallbackServerContext* context,
                                                            const v1::DescribeVolumeRequest* request,
                                                            v1::VolumeInfo* response) {
  return Answer(core_, context,
                [&](const Principal& caller) { *response = core_->volumes().Describe(request->volume_id(), caller); });
}

grpc::ServerUnaryReactor* VolumeServiceImpl::UnloadVolume(grpc::CallbackServerContext* context,
                                                          const v1::UnloadVolumeRequest* request,
                                                          v1::UnloadVolumeResponse*) {
  return Answer(core_, context,
                [&](const Principal& caller) { core_->volumes().Unload(request->volume_id(), caller); });
}

grpc::ServerUnaryReactor* SessionServiceImpl::CreateSession(grpc::CallbackServerContext* context,
                                                            const v1::CreateSessionRequest* request,
                                                            v1::CreateSessionResponse* response) {
  return new PooledReactor(context, core_, core_->setup(), "CreateSession",
                           [this, request, response](const Principal& caller, const std::atomic<bool>& stop) {
                             *response = core_->CreateSession(*request, caller, stop);
                           });
}

grpc::ServerBidiReactor<v1::ClientMessage, v1::ServerMessage>* SessionServiceImpl::StreamSession(
    grpc::CallbackServerContext* context) {
  return new SessionStreamReactor(context, core_);
}

grpc::ServerUnaryReactor* SessionServiceImpl::Snapshot(grpc::CallbackServerContext* context,
                                                       const v1::SnapshotRequest* request,
                                                       v1::SnapshotResponse* response) {
  return new SnapshotReactor(context, core_, request, response);
}

grpc::ServerWriteReactor<v1::SnapshotUpdate>* SessionServiceImpl::StreamSnapshot(grpc::CallbackServerContext* context,
                                                                                 const v1::SnapshotRequest* request) {
  auto* reactor = new SnapshotStreamReactor;
  const grpc::Status status = Guarded([&] {
    ServiceCore::SnapshotCallbacks callbacks;
    callbacks.progress = [reactor](const v1::SnapshotProgress& p) { reactor->Offer(p); };
    callbacks.done = [reactor](grpc::Status s, v1::SnapshotResponse r) {
      reactor->Complete(std::move(s), std::move(r));
    };
    core_->Snapshot(*request, core_->Authenticate(*context), reactor->cancel(), std::move(callbacks));
  });
  if (!status.ok()) reactor->Complete(status, {});
  return reactor;
}

grpc::ServerWriteReactor<v1::MovieUpdate>* SessionServiceImpl::RenderMovie(grpc::CallbackServerContext* context,
                                                                           const v1::MovieRequest* request) {
  auto* reactor = new MovieStreamReactor;
  const grpc::Status status = Guarded([&] {
    ServiceCore::MovieCallbacks callbacks;
    callbacks.progress = [reactor](const v1::MovieProgress& p) { reactor->Offer(p); };
    callbacks.done = [reactor](grpc::Status s, v1::Movie m) { reactor->Complete(std::move(s), std::move(m)); };
    core_->RenderMovie(*request, core_->Authenticate(*context), reactor->cancel(), std::move(callbacks));
  });
  if (!status.ok()) reactor->Complete(status, {});
  return reactor;
}

grpc::ServerUnaryReactor* SessionServiceImpl::CloseSession(grpc::CallbackServerContext* context,
                                                           const v1::CloseSessionRequest* request,
                                                           v1::CloseSessionResponse*) {
  return Answer(core_, context, [&](const Principal& caller) { core_->CloseSession(request->session_id(), caller); });
}

grpc::ServerWriteReactor<v1::ServerMessage>* SessionServiceImpl::WatchSession(grpc::CallbackServerContext* context,
                                                                              const v1::WatchSessionRequest* request) {
  return new WatchSessionReactor(context, core_, *request);
}

grpc::ServerUnaryReactor* SessionServiceImpl::SendEvents(grpc::CallbackServerContext* context,
                                                         const v1::SendEventsRequest* request,
                                                         v1::SendEventsResponse* response) {
  // Answered on the gRPC thread: a batch is at most 64 quick checks and merges under the session's lock.
  if (!request->grant().empty()) {  // a grant's holder: the grant decides (a link needs no token)
    grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
    reactor->Finish(Guarded([&] {
      core_->RequireBatchSize(*request);
      *response->mutable_state() = core_->sharing().SendEvents(*request, *context);
    }));
    return reactor;
  }
  return Answer(core_, context,
                [&](const Principal& caller) { *response->mutable_state() = core_->SendEvents(*request, caller); });
}

// Sharing (sharing.h): quick map work under a lock, on the gRPC thread.
grpc::ServerUnaryReactor* SessionServiceImpl::ShareSession(grpc::CallbackServerContext* context,
                                                           const v1::ShareSessionRequest* request,
                                                           v1::Grant* response) {
  return Answer(core_, context, [&](const Principal& caller) { *response = core_->sharing().Share(*request, caller); });
}

grpc::ServerUnaryReactor* SessionServiceImpl::ListShares(grpc::CallbackServerContext* context,
                                                         const v1::ListSharesRequest* request,
                                                         v1::ListSharesResponse* response) {
  return Answer(core_, context, [&](const Principal& caller) { *response = core_->sharing().List(*request, caller); });
}

grpc::ServerUnaryReactor* SessionServiceImpl::RevokeShare(grpc::CallbackServerContext* context,
                                                          const v1::RevokeShareRequest* request,
                                                          v1::RevokeShareResponse* response) {
  return Answer(core_, context,
                [&](const Principal& caller) { *response = core_->sharing().Revoke(*request, caller); });
}

grpc::ServerUnaryReactor* SessionServiceImpl::HandOver(grpc::CallbackServerContext* context,
                                                       const v1::HandOverRequest* request,
                                                       v1::HandOverResponse* response) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();  // the owner's token, or the presenter's grant
  reactor->Finish(Guarded([&] { *response = core_->sharing().HandOver(*request, *context); }));
  return reactor;
}

// Slices and picks grow with the volume (a slab, a long ray): on the reading
// pool, in the caller's queue, apart from the setup pool that CreateSession waits on.
grpc::ServerUnaryReactor* SessionServiceImpl::RenderSlice(grpc::CallbackServerContext* context,
                                                          const v1::SliceRequest* request, v1::SliceImage* response) {
  return new PooledReactor(context, core_, core_->reading(), "RenderSlice",
                           [this, request, response](const Principal& caller, const std::atomic<bool>& stop) {
                             *response = core_->RenderSlice(*request, caller, &stop);
                           });
}

grpc::ServerUnaryReactor* SessionServiceImpl::Pick(grpc::CallbackServerContext* context, const v1::PickRequest* request,
                                                   v1::PickResult* response) {
  return new PooledReactor(
      context, core_, core_->reading(), "Pick",
      [this, request, response](const Principal& caller, auto&) { *response = core_->Pick(*request, caller); });
}

grpc::ServerUnaryReactor* ServerServiceImpl::GetStatus(grpc::CallbackServerContext* context,
                                                       const v1::GetStatusRequest*, v1::ServerStatus* response) {
  return Answer(core_, context, [&](const Principal& caller) { *response = core_->Status(caller); });
}

namespace {

pacs::StudyQuery ToQuery(const v1::SearchStudiesRequest& r) {
  pacs::StudyQuery q;
  q.patient_name = r.patient_name();
  q.patient_id = r.patient_id();
  q.study_date_from = r.study_date_from();
  q.study_date_to = r.study_date_to();
  q.modality = r.modality();
  q.accession_number = r.accession_number();
  q.study_description = r.study_description();
  if (r.limit() > 0) q.limit = int(std::min<std::uint32_t>(r.limit(), 1u << 20));
  q.offset = int(std::min<std::uint32_t>(r.offset(), 1u << 30));
  return q;
}

void AddStudy(const pacs::StudySummary& from, v1::StudySummary* to) {
  to->set_study_uid(from.study_uid);
  to->set_patient_name(from.patient_name);
  to->set_patient_id(from.patient_id);
  to->set_study_date(from.study_date);
  to->set_description(from.description);
  to->set_accession_number(from.accession_number);
  for (const std::string& m : from.modalities) to->add_modalities(m);
  if (from.series_count) to->set_series_count(*from.series_count);
  if (from.instance_count) to->set_instance_count(*from.instance_count);
}

void AddSeries(const pacs::SeriesSummary& from, v1::SeriesSummary* to) {
  to->set_series_uid(from.series_uid);
  to->set_modality(from.modality);
  to->set_description(from.description);
  if (from.series_number) to->set_series_number(*from.series_number);
  if (from.instance_count) to->set_instance_count(*from.instance_count);
}

}  // namespace

grpc::ServerUnaryReactor* PacsServiceImpl::ListPacs(grpc::CallbackServerContext* context, const v1::ListPacsRequest*,
                                                    v1::ListPacsResponse* response) {
  return Answer(core_, context, [&](const Principal&) {
    for (const std::string& name : core_->pacs().Names()) response->add_names(name);
  });
}

grpc::ServerUnaryReactor* PacsServiceImpl::SearchStudies(grpc::CallbackServerContext* context,
                                                         const v1::SearchStudiesRequest* request,
                                                         v1::SearchStudiesResponse* response) {
  return new PooledReactor(
      context, core_, core_->pacs_calls(), "SearchStudies",
      [this, request, response](const Principal& caller, const std::atomic<bool>& stop) {
        const auto client = core_->pacs().Find(request->pacs(), caller);
        for (const pacs::StudySummary& study : client->SearchStudies(ToQuery(*request), &stop)) {
          AddStudy(study, response->add_studies());
        }
      },
      request->pacs());
}

grpc::ServerUnaryReactor* PacsServiceImpl::SearchSeries(grpc::CallbackServerContext* context,
                                                        const v1::SearchSeriesRequest* request,
                                                        v1::SearchSeriesResponse* response) {
  return new PooledReactor(
      context, core_, core_->pacs_calls(), "SearchSeries",
      [this, request, response](const Principal& caller, const std::atomic<bool>& stop) {
        const auto client = core_->pacs().Find(request->pacs(), caller);
        for (const pacs::SeriesSummary& series : client->SearchSeries(request->study_uid(), &stop)) {
          AddSeries(series, response->add_series());
        }
      },
      request->pacs());
}

grpc::ServerWriteReactor<v1::LoadSeriesUpdate>* PacsServiceImpl::LoadSeries(grpc::CallbackServerContext* context,
                                                                            const v1::LoadSeriesRequest* request) {
  Principal caller;
  std::shared_ptr<const pacs::DicomWebClient> client;
  std::shared_ptr<LoadSlot> slot;  // a client cannot queue loads without end
  const grpc::Status status = Guarded([&] {
    caller = core_->Authenticate(*context);
    core_->RequireServing();
    client = core_->pacs().Find(request->pacs(), caller);
    slot = core_->BeginLoad(caller);
  });
  // The call's cancelling (the caller gone, a failed write) raises the slot's flag, as Drain does.
  auto* reactor = new SeriesStreamReactor(slot ? std::shared_ptr<std::atomic<bool>>(slot, &slot->cancel) : nullptr);
  if (!status.ok()) {
    reactor->Complete(status, {});
    return reactor;
  }
  const bool queued = core_->loader().Submit(
      [this, reactor, request, caller, client, slot] {
        v1::VolumeInfo volume;
        const grpc::Status s = Guarded([&] {
          core_->RequireServing();
          volume = service::LoadSeries(*client, core_->volumes(), *request, caller, &slot->cancel,
                                       [reactor](const v1::LoadSeriesProgress& p) { reactor->Offer(p); });
        });
        slot->Release();
        reactor->Complete(s, std::move(volume));
      },
      caller.name, request->pacs());
  if (!queued) {
    slot->Release();
    reactor->Complete(RpcError::Unavailable("the server is shutting down").status(), {});
  }
  return reactor;
}

// Measurement reports (issue 57): on the PACS pool, as searches are, grouped by the PACS they go to or come from.
grpc::ServerUnaryReactor* PacsServiceImpl::StoreMeasurements(grpc::CallbackServerContext* context,
                                                             const v1::StoreMeasurementsRequest* request,
                                                             v1::StoredObject* response) {
  return new PooledReactor(
      context, core_, core_->pacs_calls(), "StoreMeasurements",
      [this, request, response](const Principal& caller, const std::atomic<bool>& stop) {
        // Its owner (or an operator), or its presenter by a principal's grant.
        const std::shared_ptr<Session> session = core_->sharing().OwnedOrPresented(request->session_id(), caller);
        const auto to = core_->pacs().Find(request->pacs(), caller, "pacs");
        const v1::SessionState state = session->CurrentState();
        if (state.scene().measurements().empty()) {
          throw RpcError::FailedPrecondition(fmt::format("session '{}' has no measurements to store", session->id()));
        }
        Principal owner;  // the volume is the owner's, whoever presents
        owner.name = session->owner();
        const VolumeMetadata& read = session->volume()->volume()->metadata();
        const PacsOrigin origin = MeasuredOrigin(core_->volumes().Describe(session->volume()->id(), owner), read);
        const auto from = core_->pacs().Find(origin.pacs, caller, "pacs");
        *response = service::StoreMeasurements(*to, *from, origin, read.frame_of_reference_uid,
                                               state.scene().measurements(), CINEVOL_VERSION, &stop);
      },
      request->pacs());
}

grpc::ServerUnaryReactor* PacsServiceImpl::LoadMeasurements(grpc::CallbackServerContext* context,
                                                            const v1::LoadMeasurementsRequest* request,
                                                            v1::LoadMeasurementsResponse* response) {
  return new PooledReactor(
      context, core_, core_->pacs_calls(), "LoadMeasurements",
      [this, request, response](const Principal& caller, const std::atomic<bool>& stop) {
        *response = service::LoadMeasurements(*core_->pacs().Find(request->pacs(), caller), *request, &stop);
      },
      request->pacs());
}

grpc::ServerUnaryReactor* PacsServiceImpl::LoadPresentation(grpc::CallbackServerContext* context,
                                                            const v1::LoadPresentationRequest* request,
                                                            v1::LoadPresentationResponse* response) {
  return new PooledReactor(
      context, core_, core_->pacs_calls(), "LoadPresentation",
      [this, request, response](const Principal& caller, const std::atomic<bool>& stop) {
        *response = service::LoadPresentation(*core_->pacs().Find(request->pacs(), caller), *request, &stop);
      },
      request->pacs());
}

// A frame is a slice (the reading pool, in the caller's queue) after one small metadata answer from the PACS.
grpc::ServerUnaryReactor* PacsServiceImpl::RenderFrame(grpc::CallbackServerContext* context,
                                                       const v1::RenderFrameRequest* request,
                                                       v1::SliceImage* response) {
  return new PooledReactor(context, core_, core_->reading(), "RenderFrame",
                           [this, request, response](const Principal& caller, const std::atomic<bool>& stop) {
                             *response = core_->RenderFrame(*request, caller, &stop);
                           });
}

}  // namespace cinevol::service
