// One scheduler per GPU (or one for the CPU): worker threads bound to the
// device take jobs from a round-robin queue and run one step each (a
// session's frame, a chunk of a still). A job with more work goes to the back
// of the queue, so sessions with work share the device fairly; a job without
// work leaves the queue until Wake puts it back, so idle sessions cost nothing.
//
// On a GPU each worker's CUDA work runs on its own per-thread default stream:
// frames of different sessions overlap on the device instead of queueing
// behind one lock. On the CPU one worker suffices (a frame uses every core).
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

namespace cinevol::service {

class Job {
 public:
  virtual ~Job() = default;
  // One step on a worker bound to the scheduler's device; returns whether the
  // job has more work now. Must not throw.
  virtual bool Step() = 0;

 private:
  friend class Scheduler;
  enum class State { kIdle, kQueued, kRunning, kRunningWoken };
  State state_ = State::kIdle;  // guarded by the scheduler's mutex
};

class Scheduler {
 public:
  // gpu: the CUDA device the workers bind to; nullopt for the CPU.
  Scheduler(std::string name, std::optional<int> gpu, int workers);
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

 private:
  void Work();

  std::string name_;
  std::optional<int> gpu_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::shared_ptr<Job>> ready_;
  bool stopping_ = false;
  std::atomic<std::int64_t> busy_ns_{0};
  std::vector<std::thread> workers_;
};

}  // namespace cinevol::service
