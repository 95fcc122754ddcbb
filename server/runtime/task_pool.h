// TaskPool: named queues of tasks run on a ThreadPool's workers, off the gRPC
// and GPU threads: the frame encoders on the process's one compute pool
// (core/thread_pool.h), volume loading and the setup of calls whose work grows
// with a volume on a pool of their own, as those tasks mostly wait (on a
// reader child, on a peer). Tasks of one queue (a caller, by name) run in
// order of submission; the queues take turns, so a caller who queues many
// slow tasks delays each other caller's next task by at most one of them per
// running task.
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <string>

#include "core/thread_pool.h"

namespace cinevol::service {

class TaskPool {
 public:
  // At most `max_running` of its tasks run at once on `pool`'s workers.
  TaskPool(std::string name, ThreadPool& pool, int max_running);
  ~TaskPool();  // Stop()
  TaskPool(const TaskPool&) = delete;
  TaskPool& operator=(const TaskPool&) = delete;

  // Waits until what is queued has run; Submit does nothing afterwards.
  void Stop();

  // `task` should not throw (the pool logs and drops what escapes). It joins
  // the back of queue `queue`; false (and dropped) once Stop has begun.
  bool Submit(std::function<void()> task, const std::string& queue = {});
  int max_running() const { return max_running_; }
  int queued() const;
  // Workers with nothing to run: what a task may borrow to split its work.
  int idle() const { return pool_.idle(); }

 private:
  // Runs tasks, the queues taking turns, until none is queued.
  void Drain();

  std::string name_;
  ThreadPool& pool_;
  const int max_running_;
  mutable std::mutex mu_;
  std::condition_variable done_cv_;  // a drain ended
  std::map<std::string, std::deque<std::function<void()>>> queues_;  // none empty
  std::deque<std::string> turns_;  // the queues with tasks, the next to run first
  int queued_ = 0;
  int draining_ = 0;  // Drain()s posted or running
  bool stopping_ = false;
};

}  // namespace cinevol::service
