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

// One caller's backlog of slow tasks keeps to its share: another caller's
// task runs beside them at once, not after one of them.
TEST(TaskPool, AQueueKeepsToItsShareOfTheRunningSlots) {
  ThreadPool workers(4);
  TaskPool pool("test", workers, {.max_running = 2, .max_running_per_queue = 1});
  std::mutex mu;
  std::condition_variable cv;
  bool release = false, bob_ran = false;
  int alice_running = 0, alice_most = 0;
  for (int i = 0; i < 3; ++i) {
    pool.Submit([&] {
      std::unique_lock lock(mu);
      alice_most = std::max(alice_most, ++alice_running);
      cv.notify_all();
      cv.wait_for(lock, 30s, [&] { return release; });
      --alice_running;
    }, "alice");
  }
  pool.Submit([&] {
    std::lock_guard lock(mu);
    bob_ran = true;
    cv.notify_all();
  }, "bob");
  {
    std::unique_lock lock(mu);
    // Bob's task ran in the other slot while Alice's first holds its own
    // (which may take its slot a moment after Bob's, on a busy machine).
    EXPECT_TRUE(cv.wait_for(lock, 30s, [&] { return bob_ran && alice_running == 1; }));
    release = true;
  }
  cv.notify_all();
  pool.Stop();
  EXPECT_EQ(alice_most, 1);
  EXPECT_EQ(pool.queued(), 0);
}

// Tasks that wait on one stalled peer (a group) hold no more than its share:
// a task of another group, even of the same caller, runs beside them.
TEST(TaskPool, AGroupKeepsToItsShareOfTheRunningSlots) {
  ThreadPool workers(4);
  TaskPool pool("test", workers, {.max_running = 3, .max_running_per_group = 2});
  std::mutex mu;
  std::condition_variable cv;
  bool release = false, healthy_ran = false;
  int stalled_running = 0, stalled_most = 0;
  for (int i = 0; i < 4; ++i) {
    pool.Submit([&] {
      std::unique_lock lock(mu);
      stalled_most = std::max(stalled_most, ++stalled_running);
      cv.notify_all();
      cv.wait_for(lock, 30s, [&] { return release; });
      --stalled_running;
    }, "user" + std::to_string(i), "stalled-pacs");
  }
  pool.Submit([&] {
    std::lock_guard lock(mu);
    healthy_ran = true;
    cv.notify_all();
  }, "user0", "healthy-pacs");
  {
    std::unique_lock lock(mu);
    EXPECT_TRUE(cv.wait_for(lock, 30s, [&] { return healthy_ran && stalled_running == 2; }));
    release = true;
  }
  cv.notify_all();
  pool.Stop();
  EXPECT_EQ(stalled_most, 2);
}

}  // namespace
}  // namespace cinevol::service
