// Scheduler: steps start while the pixels of the steps running stay within
// the budget, one step always may, and without a budget the workers bound.
// Its throughput counts only windows in which steps waited for the device,
// and admission divides it among the sessions' pixels.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>
#include <thread>
#include <vector>

#include "runtime/scheduler.h"

namespace cinevol::service {
namespace {

using namespace std::chrono_literals;

// Counts the pixels of every FakeFrame stepping at once, and the most seen.
struct InFlight {
  std::atomic<std::int64_t> pixels{0}, most{0};
  std::atomic<int> steps{0};
};

// A job of `steps` steps of `pixels` each; a step holds its worker 5 ms.
class FakeFrame final : public Job {
 public:
  FakeFrame(InFlight& in_flight, std::int64_t pixels, int steps)
      : in_flight_(in_flight), pixels_(pixels), left_(steps) {}

  std::int64_t StepPixels() const override { return pixels_; }
  bool Step() override {
    const std::int64_t now = in_flight_.pixels += pixels_;
    std::int64_t most = in_flight_.most;
    while (now > most && !in_flight_.most.compare_exchange_weak(most, now)) {
    }
    std::this_thread::sleep_for(5ms);
    in_flight_.pixels -= pixels_;
    ++in_flight_.steps;
    return --left_ > 0;
  }

 private:
  InFlight& in_flight_;
  const std::int64_t pixels_;
  int left_;
};

// Runs `jobs` (pixels each) of 10 steps on 8 workers under `budget`; returns
// the most pixels seen stepping at once.
std::int64_t MostInFlight(const std::vector<std::int64_t>& jobs, std::int64_t budget) {
  InFlight in_flight;
  {
    Scheduler scheduler("test", std::nullopt, 8, budget);
    for (std::int64_t pixels : jobs) scheduler.Wake(std::make_shared<FakeFrame>(in_flight, pixels, 10));
    const auto deadline = std::chrono::steady_clock::now() + 30s;
    while (in_flight.steps < int(jobs.size()) * 10 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(1ms);
    }
    EXPECT_EQ(in_flight.steps, int(jobs.size()) * 10) << "every step ran";
  }
  return in_flight.most;
}

TEST(Scheduler, StepsRunningAtOnceStayWithinThePixelBudget) {
  // Four frames of 100 fit a budget of 400; eight jobs on eight workers would run all at once.
  const std::int64_t most = MostInFlight(std::vector<std::int64_t>(8, 100), 400);
  EXPECT_LE(most, 400);
  EXPECT_GE(most, 200) << "more than one step ran at once";
  // Small frames run many at once.
  EXPECT_GT(MostInFlight(std::vector<std::int64_t>(8, 25), 400), 100);
}

TEST(Scheduler, AStepLargerThanTheBudgetRunsAlone) {
  EXPECT_EQ(MostInFlight({1000, 1000, 1000}, 400), 1000);
}

TEST(Scheduler, WithoutABudgetTheWorkersBound) {
  EXPECT_GT(MostInFlight(std::vector<std::int64_t>(8, 100), 0), 400);
}

using Clock = ThroughputMeter::Clock;

TEST(ThroughputMeter, CountsOnlyWindowsInWhichStepsWaited) {
  const Clock::time_point t0{};
  ThroughputMeter meter({.window = 1000ms, .saturated_share = 0.9}, t0);
  meter.StepDone(500, t0 + 500ms);
  meter.StepDone(500, t0 + 1000ms);
  EXPECT_EQ(meter.saturated_rate(), 0.0) << "nothing waited: the device was not the limit";
  meter.SetWaiting(true, t0 + 1000ms);
  meter.StepDone(3000, t0 + 1500ms);
  meter.StepDone(3000, t0 + 2000ms);
  EXPECT_DOUBLE_EQ(meter.saturated_rate(), 6000.0) << "pixels a second of a window spent waiting";
  meter.SetWaiting(false, t0 + 2500ms);
  meter.StepDone(100, t0 + 3000ms);
  EXPECT_DOUBLE_EQ(meter.saturated_rate(), 6000.0) << "half a window waiting keeps the last saturated rate";
}

// A job whose steps take 2 ms each, for ever, until stopped.
class BusyFrame final : public Job {
 public:
  explicit BusyFrame(std::int64_t pixels) : pixels_(pixels) {}
  std::int64_t StepPixels() const override { return pixels_; }
  bool Step() override {
    std::this_thread::sleep_for(2ms);
    return !stop;
  }
  std::atomic<bool> stop{false};

 private:
  const std::int64_t pixels_;
};

TEST(Scheduler, AdmitsWhileEverySessionKeepsTheFrameRate) {
  Scheduler scheduler("test", std::nullopt, 1, 0);
  EXPECT_TRUE(scheduler.Admits(1000, 30)) << "no saturated rate seen yet";
  // One worker, four jobs of 1000 pixels: 500 steps a second, 500,000 pixels a second.
  std::vector<std::shared_ptr<BusyFrame>> jobs;
  for (int i = 0; i < 4; ++i) {
    jobs.push_back(std::make_shared<BusyFrame>(1000));
    scheduler.AddSessionPixels(1000);
    scheduler.Wake(jobs.back());
  }
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (scheduler.saturated_pixel_rate() == 0 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(10ms);
  }
  for (auto& job : jobs) job->stop = true;
  const double rate = scheduler.saturated_pixel_rate();
  ASSERT_GT(rate, 0) << "four jobs waiting for one worker saturate it";
  EXPECT_LT(rate, 510000.0);
  // The four sessions get rate / 4000 frames a second each; a fifth of 1000 pixels makes it rate / 5000.
  const double fifth = rate / 5000.0;
  EXPECT_TRUE(scheduler.Admits(1000, 0.9 * fifth));
  EXPECT_FALSE(scheduler.Admits(1000, 1.1 * fifth));
  EXPECT_TRUE(scheduler.Admits(1000, 0)) << "0: no check";
  scheduler.AddSessionPixels(-4000);
  EXPECT_TRUE(scheduler.Admits(1000, 1.1 * fifth)) << "the sessions ended";
}

}  // namespace
}  // namespace cinevol::service
