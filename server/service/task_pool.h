// A fixed set of CPU threads running queued tasks, off the gRPC and GPU
// threads: JPEG/PNG/EXR encoding, volume loading, the setup of calls whose
// work grows with a volume. Tasks of one queue (a caller, by name) run in
// order of submission; the queues take turns, so a caller who queues many
// slow tasks delays each other caller's next task by at most one of them per
// thread.
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace cinevol::service {

class TaskPool {
 public:
  TaskPool(std::string name, int threads);
  ~TaskPool();  // Stop()
  TaskPool(const TaskPool&) = delete;
  TaskPool& operator=(const TaskPool&) = delete;

  // Runs what is queued, then joins; Submit does nothing afterwards.
  void Stop();

  // `task` should not throw (the pool logs and drops what escapes). It joins
  // the back of queue `queue`.
  void Submit(std::function<void()> task, const std::string& queue = {});
  int threads() const { return static_cast<int>(threads_.size()); }
  int queued() const;
  // Threads with nothing to run: what a task may borrow to split its work.
  int idle() const;

 private:
  void Work();

  std::string name_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::map<std::string, std::deque<std::function<void()>>> queues_;  // none empty
  std::deque<std::string> turns_;  // the queues with tasks, the next to run first
  int queued_ = 0;
  int running_ = 0;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace cinevol::service
