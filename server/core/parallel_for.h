// ParallelFor: runs f(i) for i in [0, n) on all cores. Work is handed out in
// chunks from an atomic counter, so uneven rows balance; results depend only
// on i, never on which thread ran it.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

namespace cinevol {

// Threads to use: CINEVOL_THREADS if set, else every hardware thread.
int DefaultThreadCount();

template <class F>
void ParallelFor(std::int64_t n, F&& f, int threads = 0, std::int64_t chunk = 1) {
  if (n <= 0) return;
  if (threads <= 0) threads = DefaultThreadCount();
  threads = static_cast<int>(std::min<std::int64_t>(threads, (n + chunk - 1) / chunk));
  std::atomic<std::int64_t> next{0};
  auto worker = [&] {
    for (std::int64_t begin; (begin = next.fetch_add(chunk)) < n;) {
      const std::int64_t end = std::min(n, begin + chunk);
      for (std::int64_t i = begin; i < end; ++i) f(i);
    }
  };
  if (threads <= 1) {
    worker();
    return;
  }
  std::vector<std::jthread> pool;
  pool.reserve(threads - 1);
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
}

}  // namespace cinevol
