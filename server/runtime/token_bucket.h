// A token bucket: `rate` tokens a second, holding at most one second's worth,
// so a burst of up to `rate` passes at once and a steady flow at `rate`.
#pragma once

#include <algorithm>
#include <chrono>

namespace cinevol::service {

class TokenBucket {
 public:
  using Clock = std::chrono::steady_clock;
  TokenBucket(double rate, Clock::time_point now) : rate_(rate), tokens_(rate), at_(now) {}

  // Takes `count` tokens if they are there (none otherwise).
  bool Take(Clock::time_point now, int count = 1) {
    Refill(now);
    if (tokens_ < count) return false;
    tokens_ -= count;
    return true;
  }
  // How long until a token is there (zero: one is there now).
  Clock::duration Wait(Clock::time_point now) {
    Refill(now);
    if (tokens_ >= 1) return Clock::duration::zero();
    return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>((1 - tokens_) / rate_));
  }

 private:
  void Refill(Clock::time_point now) {
    tokens_ = std::min(rate_, tokens_ + rate_ * std::chrono::duration<double>(now - at_).count());
    at_ = now;
  }

  double rate_, tokens_;
  Clock::time_point at_;
};

}  // namespace cinevol::service
