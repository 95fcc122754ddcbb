// ThreadPool: the process's one set of compute threads, which ParallelFor
// (core/parallel_for.h) runs on, as pbrt-v4's ParallelFor runs on its
// ThreadPool. Workers start once and sleep while no loop runs; starting a
// thread per loop cost each CPU frame its ~20 passes' thread starts.
//
// The caller of a loop works on it too and never waits for a free worker:
// when every worker is busy (another session's frame, an encoder's bands)
// the caller runs the whole loop itself. So loops may run from several
// threads at once and may nest without deadlock.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <exception>
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

 private:
  struct Loop;
  void Work();
  // Runs chunks of `loop` until none are left; records an exception.
  static void RunChunks(Loop& loop);
  Loop* FindWorkLocked();

  std::mutex mu_;
  std::condition_variable work_cv_;  // a loop with room for helpers was added, or stopping
  std::condition_variable done_cv_;  // a helper left a loop
  std::list<Loop*> loops_;           // running loops that take helpers, oldest first
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace cinevol
