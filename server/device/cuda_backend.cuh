// The GPU half of the launch backends (see cpu_backend.h): device
// buffers and one generic kernel that runs a per-pixel functor, on the
// calling thread's default stream after the renderer's frame.
#pragma once

#include "device/cpu_backend.h"
#include "device/cuda_buffer.h"

namespace cinevol {

// The backend's passes overlap their launches (programmatic dependent
// launch, sm_90): a pass's blocks are scheduled while the previous pass's
// last blocks still run, and wait here, at their start, until that pass has
// finished and its writes are visible. Each pass lets the next be scheduled
// once all its own blocks have started. A denoiser's frame is a dozen short
// passes, each of which otherwise starts only after the last one drained.
// Waiting for the previous pass whole keeps stream order: it waited too.
__device__ __forceinline__ void OverlapWithAdjacentPasses() {
  asm volatile("griddepcontrol.launch_dependents;" ::: "memory");
  asm volatile("griddepcontrol.wait;" ::: "memory");
}

// Launches a backend pass on the calling thread's default stream, allowed
// to overlap the pass before it (OverlapWithAdjacentPasses).
template <class... Params, class... Args>
void LaunchPass(void (*kernel)(Params...), dim3 grid, dim3 block, Args... args) {
  cudaLaunchAttribute overlap{};
  overlap.id = cudaLaunchAttributeProgrammaticStreamSerialization;
  overlap.val.programmaticStreamSerializationAllowed = 1;
  cudaLaunchConfig_t config{};
  config.gridDim = grid;
  config.blockDim = block;
  config.stream = cudaStreamPerThread;
  config.attrs = &overlap;
  config.numAttrs = 1;
  CINEVOL_CUDA_CHECK(cudaLaunchKernelEx(&config, kernel, args...));
}

template <class F>
__global__ void ForEachPixelKernel(const F f, int width, int height) {
  OverlapWithAdjacentPasses();
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x < width && y < height) f(x, y);
}

// CudaBackend::RowWindowSums: a block sums a segment of one row, its taps
// (and the window's reach either side) evaluated once into shared memory.
inline constexpr int kRowSegment = 256;

template <class Tap, class T>
__global__ void RowWindowSumsKernel(const Tap tap, T* out, int width, int radius, int stride) {
  // Raw storage: a __shared__ array may not have a type with initialisers.
  __shared__ alignas(alignof(T)) unsigned char storage[(kRowSegment + 2 * kMaxRowReach) * sizeof(T)];
  OverlapWithAdjacentPasses();
  T* taps = reinterpret_cast<T*>(storage);
  const int y = blockIdx.y, first = blockIdx.x * kRowSegment, reach = radius * stride;
  for (int t = threadIdx.x; t < kRowSegment + 2 * reach; t += kRowSegment) {
    const int x = first - reach + t;
    taps[t] = x >= 0 && x < width ? tap(x, y) : T{};
  }
  __syncthreads();
  const int x = first + threadIdx.x;
  if (x >= width) return;
  T sum{};
  for (int k = -radius; k <= radius; ++k) sum = sum + taps[threadIdx.x + reach + k * stride];
  out[y * width + x] = sum;
}

// CudaBackend::CountInBins: a block counts a column of row segments in
// shared memory, then adds its non-zero bins to the frame's. Two rows a
// block (450 blocks for the calibrated stop's 180 rows at 720p) took 0.016
// ms less a frame than 16 rows (60 blocks) on an H100.
inline constexpr int kBinRowSegment = 256, kBinRowsPerBlock = 2;

template <int kBins, class Bin>
__global__ void CountInBinsKernel(const Bin bin, unsigned* bins, int width, int height) {
  __shared__ unsigned local[kBins];
  for (int b = threadIdx.x; b < kBins; b += blockDim.x) local[b] = 0;
  OverlapWithAdjacentPasses();
  __syncthreads();
  const int x = blockIdx.x * kBinRowSegment + threadIdx.x;
  const int last_row = min(height, (blockIdx.y + 1) * kBinRowsPerBlock);
  for (int y = blockIdx.y * kBinRowsPerBlock; y < last_row; ++y) {
    // Neighbours mostly share a bin: one atomic per bin a warp touches.
    const int b = x < width ? bin(x, y) : -1;
    const unsigned peers = __match_any_sync(0xffffffffu, b);
    if (b >= 0 && b < kBins && threadIdx.x % 32 == __ffs(peers) - 1) atomicAdd(&local[b], unsigned(__popc(peers)));
  }
  __syncthreads();
  for (int b = threadIdx.x; b < kBins; b += blockDim.x) {
    if (local[b] != 0) atomicAdd(&bins[b], local[b]);
  }
}

struct CudaBackend {
  template <class T>
  using Buffer = cuda::DeviceBuffer<T>;
  // Host memory that Buffer::Download(T*) fills at full bus speed.
  template <class T>
  using HostBuffer = cuda::PinnedBuffer<T>;
  // `count` elements of the frame's scratch for `role` (frame_scratch.h).
  template <class T>
  static T* FrameScratch(Scratch role, std::size_t count) {
    return cuda::DeviceScratch<T>(role, count);
  }

  template <class F>
  static void ForEachPixel(int width, int height, const F& f) {
    // A warp covers 32 pixels of a row: 3-4% faster than 16x8 on the
    // denoisers' passes (H200), whose taps mostly run along rows.
    const dim3 block(32, 4);
    const dim3 grid((width + block.x - 1) / block.x, (height + block.y - 1) / block.y);
    LaunchPass(ForEachPixelKernel<F>, grid, block, f, width, height);
  }

  // As CpuBackend::RowWindowSums (the same sums, in the same order).
  template <class Tap, class T>
  static void RowWindowSums(int width, int height, int radius, int stride, const Tap& tap, T* out) {
    CheckRowReach(radius, stride);
    const dim3 grid((width + kRowSegment - 1) / kRowSegment, height);
    LaunchPass(RowWindowSumsKernel<Tap, T>, grid, dim3(kRowSegment), tap, out, width, radius, stride);
  }

  // As CpuBackend::CountInBins (the same counts).
  template <int kBins, class Bin>
  static void CountInBins(int width, int height, const Bin& bin, unsigned* bins) {
    CINEVOL_CUDA_CHECK(cudaMemsetAsync(bins, 0, kBins * sizeof(unsigned), cudaStreamPerThread));
    const dim3 grid((width + kBinRowSegment - 1) / kBinRowSegment, (height + kBinRowsPerBlock - 1) / kBinRowsPerBlock);
    LaunchPass(CountInBinsKernel<kBins, Bin>, grid, dim3(kBinRowSegment), bin, bins, width, height);
  }

  // CUDA-event timing of a sequence of passes.
  class Timer {
   public:
    Timer() {
      CINEVOL_CUDA_CHECK(cudaEventCreate(&start_));
      CINEVOL_CUDA_CHECK(cudaEventCreate(&stop_));
    }
    ~Timer() {
      cudaEventDestroy(start_);
      cudaEventDestroy(stop_);
    }
    Timer(const Timer&) = delete;
    Timer& operator=(const Timer&) = delete;
    void Start() { CINEVOL_CUDA_CHECK(cudaEventRecord(start_, cudaStreamPerThread)); }
    void Stop() { CINEVOL_CUDA_CHECK(cudaEventRecord(stop_, cudaStreamPerThread)); }
    double Milliseconds() const {  // waits for the passes to finish
      CINEVOL_CUDA_CHECK(cudaEventSynchronize(stop_));
      float ms = 0;
      CINEVOL_CUDA_CHECK(cudaEventElapsedTime(&ms, start_, stop_));
      return ms;
    }

   private:
    cudaEvent_t start_ = nullptr, stop_ = nullptr;
  };
};

}  // namespace cinevol
