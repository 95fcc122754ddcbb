// The GPU's frame scratch (frame_scratch.h): sets of buffers, one per role,
// pooled per GPU by frame size.
#include <array>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "device/cuda_buffer.h"
#include "device/frame_scratch.h"

namespace cinevol {
namespace {

using cuda::DeviceBuffer;

struct ScratchSet {
  std::array<DeviceBuffer<std::byte>, kScratchRoles> buffers;
  // Recorded on its last frame's stream when given back: the next frame, on
  // another thread's stream, waits for it there, not on the host.
  cudaEvent_t done = nullptr;

  ScratchSet() { CINEVOL_CUDA_CHECK(cudaEventCreateWithFlags(&done, cudaEventDisableTiming)); }
  ~ScratchSet() { cudaEventDestroy(done); }
};

// Frames of about the same size share sets: a set serves frames whose pixel
// count has the same bit length, so its buffers grow to that class's
// largest frame and a 720p frame never holds a 4K set. Sets are kept, free
// or not: the pool holds, per class, as many as ever ran at once.
int SizeClass(std::size_t pixels) {
  int c = 0;
  while (pixels >>= 1) ++c;
  return c;
}

class ScratchPool {
 public:
  ScratchSet* Take(std::size_t pixels) {
    std::lock_guard lock(mu_);
    std::vector<ScratchSet*>& free = free_[SizeClass(pixels)];
    if (free.empty()) return sets_.emplace_back(std::make_unique<ScratchSet>()).get();
    ScratchSet* set = free.back();
    free.pop_back();
    return set;
  }
  void Give(ScratchSet* set, std::size_t pixels) {
    std::lock_guard lock(mu_);
    free_[SizeClass(pixels)].push_back(set);
  }

 private:
  std::mutex mu_;
  std::vector<std::unique_ptr<ScratchSet>> sets_;
  std::map<int, std::vector<ScratchSet*>> free_;
};

ScratchPool& PoolOf(int gpu) {
  static std::mutex mu;
  static std::map<int, std::unique_ptr<ScratchPool>> pools;  // until exit, as VolumeCache
  std::lock_guard lock(mu);
  std::unique_ptr<ScratchPool>& pool = pools[gpu];
  if (!pool) pool = std::make_unique<ScratchPool>();
  return *pool;
}

int CurrentGpu() {
  int gpu = 0;
  CINEVOL_CUDA_CHECK(cudaGetDevice(&gpu));
  return gpu;
}

// The set a FrameScratchScope took for this thread's frame, if any.
thread_local ScratchSet* scoped_set = nullptr;

// Outside a scope (tests and benches driving a renderer or a denoiser
// directly): the thread's own set on each GPU.
ScratchSet& ThreadSet(int gpu) {
  thread_local std::map<int, std::unique_ptr<ScratchSet>> sets;
  std::unique_ptr<ScratchSet>& set = sets[gpu];
  if (!set) set = std::make_unique<ScratchSet>();
  return *set;
}

}  // namespace

namespace cuda {

void* DeviceScratchBytes(Scratch role, std::size_t bytes) {
  ScratchSet& set = scoped_set ? *scoped_set : ThreadSet(CurrentGpu());
  DeviceBuffer<std::byte>& buffer = set.buffers[std::size_t(role)];
  // Grown only: cudaFree waits for the whole GPU, every session's work on it.
  if (buffer.capacity() < bytes) buffer.Resize(bytes);
  return buffer.data();
}

}  // namespace cuda

FrameScratchScope::FrameScratchScope(std::size_t pixels)
    : pixels_(pixels), pool_(&PoolOf(CurrentGpu())), previous_(scoped_set) {
  ScratchPool& pool = *static_cast<ScratchPool*>(pool_);
  ScratchSet* set = pool.Take(pixels);
  if (const cudaError_t e = cudaStreamWaitEvent(cudaStreamPerThread, set->done); e != cudaSuccess) {
    pool.Give(set, pixels);  // back, not lost to the pool
    CINEVOL_CUDA_CHECK(e);
  }
  scoped_set = set;
  set_ = set;
}

FrameScratchScope::~FrameScratchScope() {
  auto* set = static_cast<ScratchSet*>(set_);
  cudaEventRecord(set->done, cudaStreamPerThread);  // a destructor: an error shows at the next check
  static_cast<ScratchPool*>(pool_)->Give(set, pixels_);
  scoped_set = static_cast<ScratchSet*>(previous_);
}

}  // namespace cinevol
