// What a device delivers when it is the limit: the pixels a second its
// scheduler's steps render over windows in which work waited for it nearly
// all the time. Admission (--min-session-fps) divides it among the sessions
// placed there: round-robin gives each the same frame rate, so a session of
// P pixels among sessions of S pixels in all gets rate / (S + P) frames a
// second. Not thread-safe: the scheduler calls it under its lock.
#pragma once

#include <chrono>
#include <cstdint>

namespace cinevol::service {

struct ThroughputSettings {
  // [0.1 s; 10 s] each measurement's length: long enough to hold many frames
  // of every session, short enough to see a new load soon.
  std::chrono::milliseconds window{500};
  // [0.5; 1] the share of a window in which a ready step must have waited
  // for the device for the window to count as saturated.
  double saturated_share = 0.9;
};

class ThroughputMeter {
 public:
  using Clock = std::chrono::steady_clock;

  explicit ThroughputMeter(ThroughputSettings settings = {}, Clock::time_point now = Clock::now())
      : settings_(settings), window_start_(now) {}

  // Whether steps wait in the queue from `now` on.
  void SetWaiting(bool waiting, Clock::time_point now) {
    if (waiting == waiting_) return;
    if (waiting_) waited_ += now - waiting_since_;
    waiting_ = waiting;
    waiting_since_ = now;
  }

  // A step that rendered `pixels` ended at `now`; a window that ends is judged.
  void StepDone(std::int64_t pixels, Clock::time_point now) {
    pixels_ += pixels;
    const Clock::duration length = now - window_start_;
    if (length < settings_.window) return;
    const Clock::duration waited = waited_ + (waiting_ ? now - waiting_since_ : Clock::duration::zero());
    const double seconds = std::chrono::duration<double>(length).count();
    if (std::chrono::duration<double>(waited).count() >= settings_.saturated_share * seconds) {
      saturated_rate_ = double(pixels_) / seconds;
    }
    window_start_ = now;
    waiting_since_ = now;
    waited_ = Clock::duration::zero();
    pixels_ = 0;
  }

  // Pixels a second in the last saturated window; 0 before one was seen.
  double saturated_rate() const { return saturated_rate_; }

 private:
  const ThroughputSettings settings_;
  Clock::time_point window_start_;
  bool waiting_ = false;
  Clock::time_point waiting_since_{};
  Clock::duration waited_{};
  std::int64_t pixels_ = 0;
  double saturated_rate_ = 0;
};

}  // namespace cinevol::service
