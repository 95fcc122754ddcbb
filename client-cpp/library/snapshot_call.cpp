// StreamStill: a ClientReadReactor over StreamSnapshot and the wait for it.
#include "snapshot_call.h"

#include <fmt/format.h>

#include <algorithm>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>

namespace cinevol {
namespace {

using Clock = std::chrono::steady_clock;

// How often a waiting caller looks at SnapshotOptions::cancel.
constexpr auto kCancelPoll = std::chrono::milliseconds(100);

std::string Duration(double seconds) {
  if (seconds < 90) return fmt::format("{:.0f} s", seconds);
  return fmt::format("{}m{:02d}s", int(seconds) / 60, int(seconds) % 60);
}

class StillReader final : public grpc::ClientReadReactor<v1::SnapshotUpdate> {
 public:
  StillReader(v1::SessionService::Stub& stub, std::unique_ptr<grpc::ClientContext> context,
              const v1::SnapshotRequest& request)
      : context_(std::move(context)), request_(request) {
    stub.async()->StreamSnapshot(context_.get(), &request_, this);
    StartRead(&update_);
    StartCall();
  }

  void OnReadDone(bool ok) override {
    if (!ok) return;  // the stream ended: OnDone follows
    {
      std::lock_guard lock(mu_);
      heard_ = Clock::now();
      if (update_.has_still()) still_ = std::move(*update_.mutable_still());
      if (update_.has_progress()) fresh_ = update_.progress();
    }
    changed_.notify_all();
    StartRead(&update_);
  }

  void OnDone(const grpc::Status& status) override {
    {
      std::lock_guard lock(mu_);
      status_ = status;
    }
    changed_.notify_all();
  }

  v1::SnapshotResponse Wait(const SnapshotOptions& options, std::chrono::milliseconds silence) {
    const Clock::time_point start = Clock::now();
    std::unique_lock lock(mu_);
    heard_ = start;
    while (!status_) {
      if (fresh_) {
        last_ = *std::exchange(fresh_, std::nullopt);
        if (options.on_progress) Report(lock, options.on_progress);
        continue;
      }
      const Clock::time_point now = Clock::now();
      if (options.cancel && *options.cancel) {
        GiveUp(lock, {grpc::StatusCode::CANCELLED, "the snapshot was cancelled"});
      } else if (options.timeout.count() > 0 && now - start >= options.timeout) {
        GiveUp(lock, {grpc::StatusCode::DEADLINE_EXCEEDED, TimeoutMessage(options.timeout, now - start)});
      } else if (now - heard_ >= silence) {
        GiveUp(lock, {grpc::StatusCode::DEADLINE_EXCEEDED, SilenceMessage(silence)});
      }
      Clock::time_point wake = heard_ + silence;
      if (options.timeout.count() > 0) wake = std::min(wake, start + options.timeout);
      if (options.cancel) wake = std::min(wake, now + kCancelPoll);
      changed_.wait_until(lock, wake);
    }
    if (given_up_) throw RpcError(*given_up_);
    if (!status_->ok()) throw RpcError(*status_);
    if (!still_) throw RpcError({grpc::StatusCode::INTERNAL, "the server ended the snapshot without its image"});
    return std::move(*still_);
  }

 private:
  // Calls the caller's callback outside the lock; if it throws, the call
  // ends before the exception leaves (the reactor must outlive the call).
  void Report(std::unique_lock<std::mutex>& lock, const std::function<void(const v1::SnapshotProgress&)>& report) {
    const v1::SnapshotProgress progress = *last_;
    lock.unlock();
    try {
      report(progress);
    } catch (...) {
      lock.lock();
      GiveUp(lock, {grpc::StatusCode::CANCELLED, "the snapshot's progress callback failed"});
      throw;
    }
    lock.lock();
  }

  // Cancels the call and waits for its end (the reactor must outlive it).
  void GiveUp(std::unique_lock<std::mutex>& lock, grpc::Status why) {
    if (given_up_) return;
    given_up_ = std::move(why);
    context_->TryCancel();
    changed_.wait(lock, [this] { return status_.has_value(); });
  }

  std::string Where() const {
    if (!last_ || last_->spp_done() == 0) return "before its first samples";
    return fmt::format("at {} of {} spp", last_->spp_done(), last_->spp());
  }

  std::string TimeoutMessage(std::chrono::milliseconds timeout, Clock::duration waited) const {
    std::string pace;
    if (last_ && last_->spp_done() > 0 && last_->elapsed_us() > 0) {
      const double left = last_->elapsed_us() * 1e-6 * (last_->spp() - last_->spp_done()) / last_->spp_done();
      pace = fmt::format("; it needed about {} more at its pace", Duration(left));
    }
    return fmt::format(
        "the snapshot did not finish within its timeout of {} (stopped {} after {}{}): allow more time, or ask for "
        "fewer samples per pixel or a smaller image",
        Duration(timeout.count() / 1e3), Where(), Duration(std::chrono::duration<double>(waited).count()), pace);
  }

  std::string SilenceMessage(std::chrono::milliseconds silence) const {
    return fmt::format(
        "the server reported no progress on the snapshot for {} ({}): it is stuck, overloaded or out of reach; the "
        "snapshot was cancelled. Its log may say why; try again later",
        Duration(silence.count() / 1e3), Where());
  }

  std::unique_ptr<grpc::ClientContext> context_;
  const v1::SnapshotRequest request_;
  v1::SnapshotUpdate update_;  // the read in flight

  std::mutex mu_;
  std::condition_variable changed_;
  Clock::time_point heard_;
  std::optional<v1::SnapshotProgress> fresh_;  // not yet shown to the caller
  std::optional<v1::SnapshotProgress> last_;   // the newest shown
  std::optional<v1::SnapshotResponse> still_;
  std::optional<grpc::Status> status_;    // set by OnDone
  std::optional<grpc::Status> given_up_;  // why the caller cancelled
};

}  // namespace

std::string DescribeProgress(const v1::SnapshotProgress& p) {
  if (p.spp_done() == 0) return fmt::format("0/{} spp, waiting for the first samples", p.spp());
  const double elapsed = p.elapsed_us() * 1e-6;
  const double left = elapsed * (p.spp() - p.spp_done()) / p.spp_done();
  return fmt::format("{}/{} spp, {}, about {} left", p.spp_done(), p.spp(), Duration(elapsed), Duration(left));
}

v1::SnapshotResponse StreamStill(v1::SessionService::Stub& stub, std::unique_ptr<grpc::ClientContext> context,
                                 const v1::SnapshotRequest& request, const SnapshotOptions& options,
                                 std::chrono::milliseconds silence) {
  StillReader reader(stub, std::move(context), request);
  return reader.Wait(options, silence);
}

}  // namespace cinevol
