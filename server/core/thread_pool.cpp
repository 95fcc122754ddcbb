// ThreadPool: persistent workers that help whichever loops are running.
#include "core/thread_pool.h"

#include <algorithm>
#include <atomic>

#include "core/parallel_for.h"

namespace cinevol {

struct ThreadPool::Loop {
  std::int64_t n = 0, chunk = 1;
  Body body = nullptr;
  void* context = nullptr;
  std::atomic<std::int64_t> next{0};
  int helper_room = 0;  // helpers that may still join (guarded by mu_)
  int helpers_in = 0;   // helpers inside (guarded by mu_)
  std::mutex error_mu;
  std::exception_ptr error;

  bool HasWork() const { return helper_room > 0 && next.load(std::memory_order_relaxed) < n; }
};

ThreadPool::ThreadPool(int workers) {
  threads_.reserve(std::size_t(std::max(workers, 0)));
  for (int i = 0; i < workers; ++i) threads_.emplace_back([this] { Work(); });
}

ThreadPool::~ThreadPool() {  // the workers run the tasks still queued before they leave
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  work_cv_.notify_all();
  for (std::thread& t : threads_) t.join();
}

ThreadPool& ThreadPool::Shared() {
  static ThreadPool* const pool = new ThreadPool(DefaultThreadCount() - 1);  // never destroyed, see the header
  return *pool;
}

void ThreadPool::RunChunks(Loop& loop) {
  for (std::int64_t begin; (begin = loop.next.fetch_add(loop.chunk, std::memory_order_relaxed)) < loop.n;) {
    try {
      loop.body(loop.context, begin, std::min(loop.n, begin + loop.chunk));
    } catch (...) {
      std::lock_guard lock(loop.error_mu);
      if (!loop.error) loop.error = std::current_exception();
      loop.next.store(loop.n, std::memory_order_relaxed);  // the chunks not started are skipped
    }
  }
}

ThreadPool::Loop* ThreadPool::FindWorkLocked() {
  for (Loop* loop : loops_) {
    if (loop->HasWork()) return loop;
  }
  return nullptr;
}

void ThreadPool::Work() {
  std::unique_lock lock(mu_);
  for (;;) {
    Loop* loop = nullptr;
    work_cv_.wait(lock, [&] { return (loop = FindWorkLocked()) != nullptr || !tasks_.empty() || stopping_; });
    if (loop == nullptr && tasks_.empty()) return;  // stopping, nothing left
    ++busy_;
    if (loop != nullptr) {
      --loop->helper_room;
      ++loop->helpers_in;
      lock.unlock();
      RunChunks(*loop);
      lock.lock();
      if (--loop->helpers_in == 0) done_cv_.notify_all();
    } else {
      std::function<void()> task = std::move(tasks_.front());
      tasks_.pop_front();
      lock.unlock();
      task();
      task = nullptr;  // what it holds is released outside the lock
      lock.lock();
    }
    --busy_;
  }
}

void ThreadPool::Post(std::function<void()> task) {
  if (threads_.empty()) {
    task();
    return;
  }
  {
    std::lock_guard lock(mu_);
    tasks_.push_back(std::move(task));
  }
  work_cv_.notify_one();
}

int ThreadPool::idle() const {
  std::lock_guard lock(mu_);
  return std::max(0, workers() - busy_ - int(tasks_.size()));
}

void ThreadPool::Run(std::int64_t n, std::int64_t chunk, int max_threads, Body body, void* context) {
  if (n <= 0) return;
  chunk = std::max<std::int64_t>(chunk, 1);
  const std::int64_t chunks = (n + chunk - 1) / chunk;
  const int helpers = int(std::min<std::int64_t>({std::int64_t(max_threads) - 1, chunks - 1, workers()}));
  Loop loop;
  loop.n = n;
  loop.chunk = chunk;
  loop.body = body;
  loop.context = context;
  if (helpers > 0) {
    {
      std::lock_guard lock(mu_);
      loop.helper_room = helpers;
      loops_.push_back(&loop);
    }
    if (helpers == 1) {
      work_cv_.notify_one();
    } else {
      work_cv_.notify_all();
    }
  }
  RunChunks(loop);
  if (helpers > 0) {
    // No helper joins once the loop is off the list; those inside finish
    // their chunks (every chunk is taken by now).
    std::unique_lock lock(mu_);
    loops_.remove(&loop);
    done_cv_.wait(lock, [&] { return loop.helpers_in == 0; });
  }
  if (loop.error) std::rethrow_exception(loop.error);
}

}  // namespace cinevol
