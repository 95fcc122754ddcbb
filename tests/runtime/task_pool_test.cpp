// TaskPool: tasks run off the caller's thread, in order within a queue, and
// queues take turns, so one caller's backlog does not hold another's task.
#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "runtime/task_pool.h"

namespace cinevol::service {
namespace {

using namespace std::chrono_literals;

TEST(TaskPool, QueuesTakeTurns) {
  ThreadPool workers(2);
  TaskPool pool("test", workers, 1);
  std::mutex mu;
  std::condition_variable cv;
  bool started = false, release = false;
  std::vector<std::string> order;
  // The one thread is held while the queues fill.
  pool.Submit([&] {
    std::unique_lock lock(mu);
    started = true;
    cv.notify_all();
    cv.wait_for(lock, 30s, [&] { return release; });
  });
  {
    std::unique_lock lock(mu);
    ASSERT_TRUE(cv.wait_for(lock, 30s, [&] { return started; }));
  }
  auto record = [&](std::string what) {
    return [&, what] {
      std::lock_guard lock(mu);
      order.push_back(what);
    };
  };
  for (int i = 0; i < 3; ++i) pool.Submit(record("alice" + std::to_string(i)), "alice");
  pool.Submit(record("bob0"), "bob");
  pool.Submit(record("carol0"), "carol");
  pool.Submit(record("bob1"), "bob");
  EXPECT_EQ(pool.queued(), 6);
  {
    std::lock_guard lock(mu);
    release = true;
  }
  cv.notify_all();
  pool.Stop();  // waits for what is queued
  const std::vector<std::string> expected{"alice0", "bob0", "carol0", "alice1", "bob1", "alice2"};
  EXPECT_EQ(order, expected);
  EXPECT_EQ(pool.queued(), 0);
}

TEST(TaskPool, OneQueueRunsInOrderOfSubmission) {
  ThreadPool workers(2);
  TaskPool pool("test", workers, 1);
  std::vector<int> order;
  for (int i = 0; i < 50; ++i) pool.Submit([&order, i] { order.push_back(i); });
  pool.Stop();
  ASSERT_EQ(order.size(), 50u);
  for (int i = 0; i < 50; ++i) EXPECT_EQ(order[i], i);
}

TEST(TaskPool, RunsAtMostItsShareOfThePool) {
  ThreadPool workers(4);
  TaskPool pool("test", workers, 2);
  std::mutex mu;
  int running = 0, most = 0;
  for (int i = 0; i < 40; ++i) {
    pool.Submit([&] {
      {
        std::lock_guard lock(mu);
        most = std::max(most, ++running);
      }
      std::this_thread::sleep_for(1ms);
      std::lock_guard lock(mu);
      --running;
    });
  }
  pool.Stop();
  EXPECT_LE(most, 2);
  EXPECT_GE(most, 1);
}

}  // namespace
}  // namespace cinevol::service
