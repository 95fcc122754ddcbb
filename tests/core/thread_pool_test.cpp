// The shared thread pool ParallelFor runs on: every index once, from any
// thread, nested, with exceptions carried back to the caller.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "core/parallel_for.h"
#include "core/thread_pool.h"

namespace cinevol {
namespace {

TEST(ThreadPool, RunsEveryIndexOnceInChunks) {
  ThreadPool pool(3);
  std::vector<std::atomic<int>> seen(1001);
  struct Context {
    std::vector<std::atomic<int>>* seen;
  } context{&seen};
  pool.Run(1001, 7, 4, [](void* c, std::int64_t begin, std::int64_t end) {
    for (std::int64_t i = begin; i < end; ++i) ++(*static_cast<Context*>(c)->seen)[std::size_t(i)];
  }, &context);
  for (const auto& count : seen) EXPECT_EQ(count.load(), 1);
}

TEST(ThreadPool, StartsItsWorkersOnceNotPerLoop) {
  std::set<std::thread::id> threads;
  std::mutex mu;
  for (int loop = 0; loop < 50; ++loop) {
    ParallelFor(64, [&](std::int64_t) {
      std::this_thread::sleep_for(std::chrono::microseconds(50));
      std::lock_guard lock(mu);
      threads.insert(std::this_thread::get_id());
    });
  }
  EXPECT_LE(int(threads.size()), ThreadPool::Shared().workers() + 1) << "the pool's workers and this thread";
}

TEST(ThreadPool, OneThreadRunsOnTheCaller) {
  const std::thread::id caller = std::this_thread::get_id();
  ParallelFor(100, [&](std::int64_t) { EXPECT_EQ(std::this_thread::get_id(), caller); }, 1);
}

TEST(ThreadPool, LoopsNestAndRunFromSeveralThreadsAtOnce) {
  std::atomic<std::int64_t> sum{0};
  std::vector<std::thread> callers;
  for (int t = 0; t < 4; ++t) {
    callers.emplace_back([&] {
      ParallelFor(20, [&](std::int64_t i) { ParallelFor(30, [&](std::int64_t j) { sum += i * 30 + j; }); });
    });
  }
  for (std::thread& t : callers) t.join();
  EXPECT_EQ(sum.load(), 4 * (600 * 599 / 2));
}

TEST(ThreadPool, ACallerGetsTheFirstExceptionAfterTheOthersFinish) {
  std::atomic<int> running{0};
  EXPECT_THROW(ParallelFor(1000, [&](std::int64_t i) {
    ++running;
    if (i == 10) {
      --running;
      throw std::runtime_error("row 10");
    }
    --running;
  }), std::runtime_error);
  EXPECT_EQ(running.load(), 0) << "no chunk still runs once the loop has thrown";
  int after = 0;
  ParallelFor(10, [&](std::int64_t) { ++after; }, 1);
  EXPECT_EQ(after, 10) << "the pool works on";
}

TEST(ThreadPool, PostedTasksRunOnAWorkerInOrderAndMayRunLoops) {
  ThreadPool pool(1);
  const std::thread::id caller = std::this_thread::get_id();
  std::mutex mu;
  std::condition_variable cv;
  std::vector<int> order;
  std::atomic<std::int64_t> sum{0};
  for (int i = 0; i < 5; ++i) {
    pool.Post([&, i] {
      EXPECT_NE(std::this_thread::get_id(), caller);
      ParallelFor(100, [&](std::int64_t j) { sum += j; });  // a task's loop: an encode's bands
      std::lock_guard lock(mu);
      order.push_back(i);
      cv.notify_all();
    });
  }
  std::unique_lock lock(mu);
  ASSERT_TRUE(cv.wait_for(lock, std::chrono::seconds(30), [&] { return order.size() == 5; }));
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_EQ(sum.load(), 5 * 4950);
}

TEST(ThreadPool, WithoutWorkersATaskRunsOnItsPoster) {
  ThreadPool pool(0);
  const std::thread::id caller = std::this_thread::get_id();
  bool ran = false;
  pool.Post([&] { ran = std::this_thread::get_id() == caller; });
  EXPECT_TRUE(ran);
  EXPECT_EQ(pool.idle(), 0);
}

}  // namespace
}  // namespace cinevol
