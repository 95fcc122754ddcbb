#include "service/still_job.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>

#include "core/error.h"
#include "runtime/errors.h"

namespace cinevol::service {
namespace {

// How long one step of a still should take: other sessions' frames on the
// same device wait at most this long behind it, a cancel is seen within it,
// and progress is reported at about this pace.
constexpr auto kStillStep = std::chrono::milliseconds(250);
// Progress updates at most this often (each is a message to the client).
constexpr auto kProgressPeriod = std::chrono::milliseconds(500);

}  // namespace

StillJob::StillJob(std::shared_ptr<VolumeLease> volume, std::shared_ptr<VolumeLease> fused, v1::Scene scene, int spp,
                   int max_chunk_spp, Backend backend, std::shared_ptr<std::atomic<bool>> cancel, Callbacks callbacks)
    : volume_(std::move(volume)),
      fused_(std::move(fused)),
      scene_(std::move(scene)),
      spp_(spp),
      max_chunk_(max_chunk_spp),
      backend_(backend),
      cancel_(std::move(cancel)),
      callbacks_(std::move(callbacks)) {}

StillJob::~StillJob() {
  if (callbacks_.done) callbacks_.done(RpcError::Cancelled("the server is shutting down").status(), {});
}

std::int64_t StillJob::StepPixels() const { return std::int64_t(scene_.render().width()) * scene_.render().height(); }

bool StillJob::Step() {
  try {
    if (*cancel_) throw Cancelled("the still was cancelled");
    if (!pipeline_) Start();
    const Clock::time_point begin = Clock::now();
    const int chunk = std::min(chunk_, spp_ - pipeline_->accumulated_spp());
    pipeline_->Accumulate(chunk);
    AdaptChunk(chunk, Clock::now() - begin);
    if (!pipeline_->Converged()) {
      ReportProgress();
      return true;
    }
    Finish();
  } catch (...) {
    const int done = pipeline_ ? pipeline_->accumulated_spp() : 0;
    pipeline_.reset();
    std::exchange(callbacks_.done, nullptr)(Failure(std::current_exception(), done), {});
  }
  return false;
}

void StillJob::Start() {
  start_ = Clock::now();
  pipeline_ = std::make_unique<FramePipeline>(backend_, volume_->phase(int(scene_.time().phase())), RendererOptions{},
                                              volume_->labels());
  if (fused_) pipeline_->SetFusedVolume(fused_->volume());
  pipeline_->SetCancel(cancel_.get());
  FrameSettings settings;
  settings.denoiser.method = DenoiseMethod::kNone;
  settings.target_spp = spp_;
  pipeline_->Update(scene_, settings);
}

// The next chunk aims at kStillStep, growing at most twofold a step.
void StillJob::AdaptChunk(int chunk, Clock::duration took) {
  const double ratio =
      std::chrono::duration<double>(kStillStep).count() / std::max(1e-4, std::chrono::duration<double>(took).count());
  chunk_ = std::clamp(int(chunk * std::min(2.0, ratio)), 1, max_chunk_);
}

void StillJob::ReportProgress() {
  const Clock::time_point now = Clock::now();
  if (!callbacks_.progress || now - last_progress_ < kProgressPeriod) return;
  last_progress_ = now;
  v1::SnapshotProgress p;
  p.set_spp_done(std::uint32_t(pipeline_->accumulated_spp()));
  p.set_spp(std::uint32_t(spp_));
  p.set_elapsed_us(std::uint64_t(std::chrono::duration_cast<std::chrono::microseconds>(now - start_).count()));
  callbacks_.progress(p);
}

// The error's status; a cancel says what cancelled it and how far it came.
grpc::Status StillJob::Failure(std::exception_ptr error, int done) const {
  const grpc::Status status = ToStatus(error);
  if (status.error_code() != grpc::StatusCode::CANCELLED || !*cancel_ || !callbacks_.why_cancelled) return status;
  return RpcError::Cancelled(
             fmt::format("the still stopped at {} of {} spp: {}", done, spp_, callbacks_.why_cancelled()))
      .status();
}

void StillJob::Finish() {
  StillRadiance still;
  still.image = pipeline_->AccumulatedRadiance();
  still.exposure = pipeline_->exposure();
  still.spp = spp_;
  pipeline_.reset();
  still.render_us = std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - start_).count();
  std::exchange(callbacks_.done, nullptr)(grpc::Status::OK, std::move(still));
}

}  // namespace cinevol::service
