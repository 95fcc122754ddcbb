// ThreadPool: the process's one set of compute threads, which ParallelFor
// (core/parallel_for.h) runs on, as pbrt-v4's ParallelFor runs on its
// ThreadPool. Workers start once and sleep while no loop runs; starting a
// thread per loop cost each CPU frame its ~20 passes' thread starts.
//
// The caller of a loop works on it too and never waits for a free worker:
// when every worker is busy (another session's frame, an encode) the caller
// runs the whole loop itself. So loops may run from several threads at once
// and may nest without deadlock.
//
// Workers also run posted tasks (the frame encoders: service/task_pool.h),
// but only while no loop has room for them: a loop's caller, a frame in
// flight, waits on its chunks, while a task waits in a queue anyway.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <functional>
#include <list>
#include <mutex>
#include <thread>
#include <vector>

namespace cinevol {

class ThreadPool {
 public:
  // `workers` threads besides the callers (0: every loop runs on its caller).
  explicit ThreadPool(int workers);
  ~ThreadPool();  // joins the workers; no loop may be running
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  // The process's pool: DefaultThreadCount() - 1 workers, started on first
  // use and never destroyed (a loop may still run on a detached thread
  // while static destructors do).
  static ThreadPool& Shared();

  int workers() const { return static_cast<int>(threads_.size()); }

  // body(context, begin, end) over [0, n) in chunks of `chunk`; at most
  // `max_threads` threads take part, the caller included. The first
  // exception a chunk throws stops the chunks not yet started and is
  // rethrown here once the others have finished.
  using Body = void (*)(void* context, std::int64_t begin, std::int64_t end);
  void Run(std::int64_t n, std::int64_t chunk, int max_threads, Body body, void* context);

  // Runs `task` on a worker, after the tasks posted before it; with no
  // workers, on the caller now. `task` must not throw.
  void Post(std::function<void()> task);
  // Workers running neither a loop nor a task, less the tasks waiting.
  int idle() const;

 private:
  struct Loop;
  void Work();
  // Runs chunks of `loop` until none are left; records an exception.
  static void RunChunks(Loop& loop);
  Loop* FindWorkLocked();

  mutable std::mutex mu_;
  std::condition_variable work_cv_;  // a loop with room for helpers or a task was added, or stopping
  std::condition_variable done_cv_;  // a helper left a loop
  std::list<Loop*> loops_;           // running loops that take helpers, oldest first
  std::deque<std::function<void()>> tasks_;  // posted, not started
  int busy_ = 0;                             // workers inside a loop or a task
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace cinevol
