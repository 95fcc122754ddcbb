// A still on a session's device (Snapshot, and each frame of RenderMovie):
// `spp` samples accumulated a chunk per step with the still's own pipeline
// (the session's history stays untouched). Between chunks (and between rows
// of a chunk on the CPU) it checks whether anyone still wants the result. A
// chunk's samples follow the device's pace: about kStillStep of work, never
// more than `max_chunk_spp`, so other sessions' frames interleave.
#pragma once

#include <grpcpp/support/status.h>

#include <atomic>
#include <functional>
#include <memory>
#include <string>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "core/image.h"
#include "device/device.h"
#include "pipeline/frame_pipeline.h"
#include "runtime/scheduler.h"
#include "runtime/session.h"
#include "runtime/volume_registry.h"

namespace cinevol::service {

// A still's radiance before it is tone mapped and encoded.
struct StillRadiance {
  ImageRgbF image;
  float exposure = 1;  // the scene's, for ToneMap
  int spp = 0;
  std::int64_t render_us = 0;
};

class StillJob final : public Job {
 public:
  struct Callbacks {
    // Once, on the device's worker, with the radiance or the error: hand heavy work (encoding) to another pool.
    std::function<void(grpc::Status, StillRadiance)> done;
    // After steps, at most every kProgressPeriod; may be empty.
    std::function<void(const v1::SnapshotProgress&)> progress;
    std::function<std::string()> why_cancelled;  // what raised `cancel`, for the message
  };
  // `fused`: the second volume the scene's fusion names, or null. `cancel`:
  // raised when the caller goes away or the session ends.
  StillJob(std::shared_ptr<VolumeLease> volume, std::shared_ptr<VolumeLease> fused, v1::Scene scene, int spp,
           int max_chunk_spp, Backend backend, std::shared_ptr<std::atomic<bool>> cancel, Callbacks callbacks);
  // A still dropped unfinished (the server stopping) still answers its caller.
  ~StillJob() override;

  std::int64_t StepPixels() const override;
  bool Step() override;

 private:
  void Start();
  void AdaptChunk(int chunk, Clock::duration took);
  void ReportProgress();
  grpc::Status Failure(std::exception_ptr error, int done) const;
  void Finish();

  std::shared_ptr<VolumeLease> volume_, fused_;
  v1::Scene scene_;
  int spp_, max_chunk_;
  int chunk_ = 1;  // the first step is short, whatever the device: progress comes soon
  Backend backend_;
  std::shared_ptr<std::atomic<bool>> cancel_;  // the pipeline's frames check it too
  Callbacks callbacks_;
  std::unique_ptr<FramePipeline> pipeline_;
  Clock::time_point start_, last_progress_;
};

}  // namespace cinevol::service
