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

void TaskPool::Submit(std::function<void()> task) {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return;
    tasks_.push_back(std::move(task));
  }
  cv_.notify_one();
}

int TaskPool::queued() const {
  std::lock_guard lock(mu_);
  return static_cast<int>(tasks_.size());
}

int TaskPool::idle() const {
  std::lock_guard lock(mu_);
  return std::max(0, threads() - running_ - static_cast<int>(tasks_.size()));
}

void TaskPool::Work() {
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return stopping_ || !tasks_.empty(); });
      if (tasks_.empty()) return;  // stopping, nothing left
      task = std::move(tasks_.front());
      tasks_.pop_front();
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
