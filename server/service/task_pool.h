// A fixed set of CPU threads running queued tasks in order of submission:
// JPEG/PNG/EXR encoding and volume loading, off the gRPC and GPU threads.
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
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

  // `task` should not throw (the pool logs and drops what escapes).
  void Submit(std::function<void()> task);
  int threads() const { return static_cast<int>(threads_.size()); }
  int queued() const;
  // Threads with nothing to run: what a task may borrow to split its work.
  int idle() const;

 private:
  void Work();

  std::string name_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> tasks_;
  int running_ = 0;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace cinevol::service
