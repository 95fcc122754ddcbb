// TaskPool: fair queues over a ThreadPool.
#include "runtime/task_pool.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <exception>

#include "core/log_safe.h"

namespace cinevol::service {

namespace {
int ShareOf(int max_running, int share) { return share > 0 ? std::min(share, max_running) : max_running; }
}  // namespace

TaskPool::TaskPool(std::string name, ThreadPool& pool, Shares shares)
    : name_(std::move(name)),
      pool_(pool),
      max_running_(std::max(shares.max_running, 1)),
      max_running_per_queue_(ShareOf(max_running_, shares.max_running_per_queue)),
      max_running_per_group_(ShareOf(max_running_, shares.max_running_per_group)) {}

TaskPool::~TaskPool() { Stop(); }

void TaskPool::Stop() {
  std::unique_lock lock(mu_);
  stopping_ = true;
  done_cv_.wait(lock, [&] { return draining_ == 0; });
}

bool TaskPool::Submit(std::function<void()> task, const std::string& queue, const std::string& group) {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return false;
    std::deque<Task>& tasks = queues_[queue].tasks;
    if (tasks.empty()) turns_.push_back(queue);
    tasks.push_back({std::move(task), group});
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

bool TaskPool::TakeLocked(Task& task, std::string& queue) {
  // The first queue in turn whose oldest task is within its queue's and
  // group's shares gives that task, then waits behind the others.
  for (auto turn = turns_.begin(); turn != turns_.end(); ++turn) {
    Queue& q = queues_.at(*turn);
    const std::string& group = q.tasks.front().group;
    if (q.running >= max_running_per_queue_) continue;
    if (!group.empty() && groups_.count(group) && groups_[group] >= max_running_per_group_) continue;
    queue = std::move(*turn);
    turns_.erase(turn);
    task = std::move(q.tasks.front());
    q.tasks.pop_front();
    if (!q.tasks.empty()) turns_.push_back(queue);
    ++q.running;
    if (!task.group.empty()) ++groups_[task.group];
    --queued_;
    return true;
  }
  return false;
}

void TaskPool::EndLocked(const Task& task, const std::string& queue) {
  auto q = queues_.find(queue);
  if (--q->second.running == 0 && q->second.tasks.empty()) queues_.erase(q);
  if (task.group.empty()) return;
  auto g = groups_.find(task.group);
  if (--g->second == 0) groups_.erase(g);
}

void TaskPool::Drain() {
  for (;;) {
    Task task;
    std::string queue;
    {
      std::lock_guard lock(mu_);
      if (!TakeLocked(task, queue)) {  // what waits is at its share: the drains running it take it next
        --draining_;
        done_cv_.notify_all();
        return;
      }
    }
    try {
      task.run();
    } catch (const std::exception& e) {  // a task's bug must not take the pool down
      spdlog::error("{} task failed: {}", name_, LogSafe(e.what()));
    }
    task.run = nullptr;  // what it holds is released outside the lock
    std::lock_guard lock(mu_);
    EndLocked(task, queue);
  }
}

}  // namespace cinevol::service
