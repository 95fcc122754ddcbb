// ParallelFor: runs f(i) for i in [0, n) on the shared ThreadPool
// (core/thread_pool.h) and the calling thread. Work is handed out in chunks
// from an atomic counter, so uneven rows balance; results depend only on i,
// never on which thread ran it.
#pragma once

#include <algorithm>  // users of the thread-per-call version got these from here
#include <atomic>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "core/thread_pool.h"

namespace cinevol {

// Threads to use: CINEVOL_THREADS if set, else every hardware thread.
int DefaultThreadCount();

// `threads`: at most this many threads take part, the caller included (0:
// every thread of the pool); 1 runs the loop on the caller alone. f may
// throw: the first exception stops the chunks not yet started and is
// rethrown once the others are done.
template <class F>
void ParallelFor(std::int64_t n, F&& f, int threads = 0, std::int64_t chunk = 1) {
  if (n <= 0) return;
  if (threads == 1 || n == 1) {
    for (std::int64_t i = 0; i < n; ++i) f(i);
    return;
  }
  using Body = std::remove_reference_t<F>;
  ThreadPool::Shared().Run(n, chunk, threads <= 0 ? std::numeric_limits<int>::max() : threads,
                           [](void* context, std::int64_t begin, std::int64_t end) {
                             Body& body = *static_cast<Body*>(context);
                             for (std::int64_t i = begin; i < end; ++i) body(i);
                           },
                           const_cast<void*>(static_cast<const void*>(&f)));
}

}  // namespace cinevol
