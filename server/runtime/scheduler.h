// One scheduler per GPU (or one for the CPU): worker threads bound to the
// device take jobs from a round-robin queue and run one step each (a
// session's frame, a chunk of a still). A job with more work goes to the back
// of the queue, so sessions with work share the device fairly; a job without
// work leaves the queue until Wake puts it back, so idle sessions cost nothing.
//
// On a GPU each worker's CUDA work runs on its own per-thread default stream:
// frames of different sessions overlap on the device instead of queueing
// behind one lock. What runs at once is bounded in pixels, not in steps: a
// step starts while the pixels of the steps running stay within the budget
// (one step always may). Full-size frames then run a few at a time, each
// finishing soon after its event, and small interactive frames many at a
// time, enough to keep the GPU busy (docs/performance.md, "Pixels in
// flight"). On the CPU one worker suffices (a frame uses every core).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "runtime/throughput.h"

namespace cinevol::service {

class Job {
 public:
  virtual ~Job() = default;
  // One step on a worker bound to the scheduler's device; returns whether the
  // job has more work now. Must not throw.
  virtual bool Step() = 0;
  // The pixels the next step renders, for the scheduler's budget. Called
  // under the scheduler's lock: must not block.
  virtual std::int64_t StepPixels() const = 0;

 private:
  friend class Scheduler;
  enum class State { kIdle, kQueued, kRunning, kRunningWoken };
  State state_ = State::kIdle;     // guarded by the scheduler's mutex
  std::int64_t step_pixels_ = 0;  // its running step's, against the budget; likewise
};

class Scheduler {
 public:
  // gpu: the CUDA device the workers bind to; nullopt for the CPU.
  // pixels_in_flight: the steps running at once render at most this many
  // pixels together (one step always may); 0: no bound but the workers.
  Scheduler(std::string name, std::optional<int> gpu, int workers, std::int64_t pixels_in_flight = 0);
  ~Scheduler();  // Stop()
  Scheduler(const Scheduler&) = delete;
  Scheduler& operator=(const Scheduler&) = delete;

  // Queues a step of `job` unless one is queued; if it is running, it runs
  // again afterwards.
  void Wake(std::shared_ptr<Job> job);

  // Finishes the steps under way, drops the queue and joins the workers;
  // Wake does nothing afterwards.
  void Stop();

  const std::string& name() const { return name_; }
  std::optional<int> gpu() const { return gpu_; }
  int queued() const;
  double busy_seconds() const { return busy_ns_.load() * 1e-9; }

  // Sessions placed here, for placing new ones on the least loaded device.
  std::atomic<int> sessions{0};
  std::atomic<std::uint64_t> frames_rendered{0};

  // Admission (--min-session-fps). The sessions placed here keep the sum of
  // the pixels their frames render (viewport x last scale^2) up to date.
  void AddSessionPixels(std::int64_t delta);
  // Whether a session whose frames render `pixels` may join without taking
  // every session here under `min_fps` when all want frames: round-robin
  // then gives each rate / (their pixels + `pixels`) frames a second, where
  // rate is what the device rendered while steps waited for it
  // (ThroughputMeter). Yes while no such rate has been seen, and for min_fps 0.
  bool Admits(std::int64_t pixels, double min_fps) const;
  // Pixels a second while saturated; 0 before that was seen.
  double saturated_pixel_rate() const;

 private:
  void Work();
  bool CanStartLocked() const;
  // Tells the meter whether steps wait in the queue now.
  void NoteQueueLocked() { meter_.SetWaiting(!ready_.empty(), std::chrono::steady_clock::now()); }

  std::string name_;
  std::optional<int> gpu_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::shared_ptr<Job>> ready_;
  bool stopping_ = false;
  const std::int64_t max_pixels_in_flight_;
  std::int64_t pixels_in_flight_ = 0;
  std::atomic<std::int64_t> busy_ns_{0};
  ThroughputMeter meter_;                      // guarded by mu_
  std::int64_t session_pixels_ = 0;            // likewise
  std::vector<std::thread> workers_;
};

}  // namespace cinevol::service
