// TaskPool: a queue and its threads.
#include "service/task_pool.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <exception>

#include "core/log_safe.h"

namespace cinevol::service {

TaskPool::TaskPool(std::string name, int threads) : name_(std::move(name)) {
  for (int i = 0; i < std::max(threads, 1); ++i) threads_.emplace_back([this] { Work(); });
}

TaskPool::~TaskPool() { Stop(); }

void TaskPool::Stop() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  for (std::thread& t : threads_) {
    if (t.joinable()) t.join();
  }
}

void TaskPool::Submit(std::function<void()> task, const std::string& queue) {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return;
    std::deque<std::function<void()>>& tasks = queues_[queue];
    if (tasks.empty()) turns_.push_back(queue);
    tasks.push_back(std::move(task));
    ++queued_;
  }
  cv_.notify_one();
}

int TaskPool::queued() const {
  std::lock_guard lock(mu_);
  return queued_;
}

int TaskPool::idle() const {
  std::lock_guard lock(mu_);
  return std::max(0, threads() - running_ - queued_);
}

void TaskPool::Work() {
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return stopping_ || queued_ > 0; });
      if (queued_ == 0) return;  // stopping, nothing left
      // The queue whose turn it is gives its oldest task, then waits behind the others.
      const std::string queue = std::move(turns_.front());
      turns_.pop_front();
      auto it = queues_.find(queue);
      task = std::move(it->second.front());
      it->second.pop_front();
      if (it->second.empty()) {
        queues_.erase(it);
      } else {
        turns_.push_back(queue);
      }
      --queued_;
      ++running_;
    }
    try {
      task();
    } catch (const std::exception& e) {  // a task's bug must not take the pool down
      spdlog::error("{} task failed: {}", name_, LogSafe(e.what()));
    }
    std::lock_guard lock(mu_);
    --running_;
  }
}

}  // namespace cinevol::service
