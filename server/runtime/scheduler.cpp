// Scheduler: a fair ready queue over device-bound workers.
#include "runtime/scheduler.h"

#include <spdlog/spdlog.h>

#include "device/device.h"

namespace cinevol::service {

Scheduler::Scheduler(std::string name, std::optional<int> gpu, int workers, std::int64_t pixels_in_flight)
    : name_(std::move(name)), gpu_(gpu), max_pixels_in_flight_(pixels_in_flight) {
  for (int i = 0; i < std::max(workers, 1); ++i) workers_.emplace_back([this] { Work(); });
}

Scheduler::~Scheduler() { Stop(); }

void Scheduler::Stop() {
  std::deque<std::shared_ptr<Job>> dropped;  // released outside the lock
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
    dropped.swap(ready_);
  }
  cv_.notify_all();
  for (std::thread& t : workers_) {
    if (t.joinable()) t.join();
  }
}

void Scheduler::Wake(std::shared_ptr<Job> job) {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return;
    switch (job->state_) {
      case Job::State::kIdle:
        job->state_ = Job::State::kQueued;
        ready_.push_back(std::move(job));
        NoteQueueLocked();
        break;
      case Job::State::kRunning:
        job->state_ = Job::State::kRunningWoken;
        return;
      default:
        return;
    }
  }
  cv_.notify_one();
}

void Scheduler::AddSessionPixels(std::int64_t delta) {
  std::lock_guard lock(mu_);
  session_pixels_ += delta;
}

bool Scheduler::Admits(std::int64_t pixels, double min_fps) const {
  std::lock_guard lock(mu_);
  const double rate = meter_.saturated_rate();
  if (min_fps <= 0 || rate <= 0) return true;
  return rate / double(session_pixels_ + pixels) >= min_fps;
}

double Scheduler::saturated_pixel_rate() const {
  std::lock_guard lock(mu_);
  return meter_.saturated_rate();
}

int Scheduler::queued() const {
  std::lock_guard lock(mu_);
  return static_cast<int>(ready_.size());
}

bool Scheduler::CanStartLocked() const {
  if (ready_.empty()) return false;
  return max_pixels_in_flight_ <= 0 || pixels_in_flight_ == 0 ||
         pixels_in_flight_ + ready_.front()->StepPixels() <= max_pixels_in_flight_;
}

void Scheduler::Work() {
  if (gpu_) {
    try {
      UseGpu(*gpu_);
    } catch (const std::exception& e) {
      spdlog::error("{}: cannot bind a worker to the GPU: {}", name_, e.what());
      return;
    }
  }
  for (;;) {
    std::shared_ptr<Job> job;
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return stopping_ || CanStartLocked(); });
      if (stopping_) return;
      job = std::move(ready_.front());
      ready_.pop_front();
      NoteQueueLocked();
      job->state_ = Job::State::kRunning;
      job->step_pixels_ = job->StepPixels();
      pixels_in_flight_ += job->step_pixels_;
    }
    const auto start = std::chrono::steady_clock::now();
    const bool more = job->Step();
    const auto end = std::chrono::steady_clock::now();
    busy_ns_ += std::chrono::duration_cast<std::chrono::nanoseconds>(end - start).count();
    {
      std::lock_guard lock(mu_);
      meter_.StepDone(job->step_pixels_, end);
      pixels_in_flight_ -= job->step_pixels_;
      if (max_pixels_in_flight_ > 0) cv_.notify_all();  // room for steps that waited on the budget
      if (more || job->state_ == Job::State::kRunningWoken) {
        job->state_ = Job::State::kQueued;
        ready_.push_back(std::move(job));
        NoteQueueLocked();
        cv_.notify_one();
      } else {
        job->state_ = Job::State::kIdle;
      }
    }
  }
}

}  // namespace cinevol::service
