// Thread count for ParallelFor's pool.
#include "core/parallel_for.h"

#include <algorithm>
#include <cstdlib>
#include <thread>

namespace cinevol {

int DefaultThreadCount() {
  if (const char* env = std::getenv("CINEVOL_THREADS")) {
    const int n = std::atoi(env);
    if (n > 0) return n;
  }
  return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

}  // namespace cinevol
