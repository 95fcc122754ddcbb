// TaskPool: fair queues over a ThreadPool.
#include "runtime/task_pool.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <exception>

#include "core/log_safe.h"

namespace cinevol::service {

TaskPool::TaskPool(std::string name, ThreadPool& pool, int max_running)
    : name_(std::move(name)), pool_(pool), max_running_(std::max(max_running, 1)) {}

TaskPool::~TaskPool() { Stop(); }

void TaskPool::Stop() {
  std::unique_lock lock(mu_);
  stopping_ = true;
  done_cv_.wait(lock, [&] { return draining_ == 0; });
}

bool TaskPool::Submit(std::function<void()> task, const std::string& queue) {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return false;
    std::deque<std::function<void()>>& tasks = queues_[queue];
    if (tasks.empty()) turns_.push_back(queue);
    tasks.push_back(std::move(task));
    ++queued_;
    if (draining_ >= max_running_) return true;  // a running drain takes it
    ++draining_;
  }
  pool_.Post([this] { Drain(); });
  return true;
}

int TaskPool::queued() const {
  std::lock_guard lock(mu_);
  return queued_;
}

void TaskPool::Drain() {
  for (;;) {
    std::function<void()> task;
    {
      std::lock_guard lock(mu_);
      if (queued_ == 0) {
        --draining_;
        done_cv_.notify_all();
        return;
      }
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
    }
    try {
      task();
    } catch (const std::exception& e) {  // a task's bug must not take the pool down
      spdlog::error("{} task failed: {}", name_, LogSafe(e.what()));
    }
  }
}

}  // namespace cinevol::service
