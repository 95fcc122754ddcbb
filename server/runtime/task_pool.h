// TaskPool: named queues of tasks run on a ThreadPool's workers, off the gRPC
// and GPU threads: the frame encoders on the process's one compute pool
// (core/thread_pool.h), volume loading and the setup of calls whose work grows
// with a volume on a pool of their own, as those tasks mostly wait (on a
// reader child, on a peer). Tasks of one queue (a caller, by name) run in
// order of submission; the queues take turns, and one queue runs at most
// `max_running_per_queue` tasks at once, so a caller who queues many slow
// tasks never holds every running slot: another caller's next task waits for
// none of them when a slot is kept free for it (max_running_per_queue <
// max_running), else for one. Tasks may also name a group (the PACS they
// wait on): a group runs at most `max_running_per_group` at once, so a peer
// that stalls holds no more than its share of the slots either.
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
  struct Shares {
    int max_running = 1;            // tasks at once on the pool's workers
    int max_running_per_queue = 0;  // of one queue's; 0: max_running
    int max_running_per_group = 0;  // of one named group's; 0: max_running
  };
  TaskPool(std::string name, ThreadPool& pool, Shares shares);
  TaskPool(std::string name, ThreadPool& pool, int max_running) : TaskPool(std::move(name), pool, Shares{max_running}) {}
  ~TaskPool();  // Stop()
  TaskPool(const TaskPool&) = delete;
  TaskPool& operator=(const TaskPool&) = delete;

  // Waits until what is queued has run; Submit does nothing afterwards.
  void Stop();

  // `task` should not throw (the pool logs and drops what escapes). It joins
  // the back of queue `queue`, in `group` (empty: none); false (and dropped)
  // once Stop has begun.
  bool Submit(std::function<void()> task, const std::string& queue = {}, const std::string& group = {});
  int max_running() const { return max_running_; }
  int queued() const;
  // Workers with nothing to run: what a task may borrow to split its work.
  int idle() const { return pool_.idle(); }

 private:
  struct Task {
    std::function<void()> run;
    std::string group;
  };
  struct Queue {
    std::deque<Task> tasks;
    int running = 0;
  };
  // Runs tasks, the queues taking turns, until none that may run is queued.
  void Drain();
  // The next task that may run, its queue's turn taken and counted as
  // running in `queue`; false when none may. mu_ held.
  bool TakeLocked(Task& task, std::string& queue);
  // Counts the task of `queue` as ended; mu_ held.
  void EndLocked(const Task& task, const std::string& queue);

  std::string name_;
  ThreadPool& pool_;
  const int max_running_;
  const int max_running_per_queue_;
  const int max_running_per_group_;
  mutable std::mutex mu_;
  std::condition_variable done_cv_;  // a drain ended
  std::map<std::string, Queue> queues_;  // each with tasks waiting or running
  std::map<std::string, int> groups_;    // tasks running by group, none at 0
  std::deque<std::string> turns_;  // the queues with tasks waiting, the next to run first
  int queued_ = 0;
  int draining_ = 0;  // Drain()s posted or running
  bool stopping_ = false;
};

}  // namespace cinevol::service
