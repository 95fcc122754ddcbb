// The GPU half of the launch backends (see cpu_backend.h): device
// buffers and one generic kernel that runs a per-pixel functor, on the
// calling thread's default stream after the renderer's frame.
#pragma once

#include "device/cuda_buffer.h"

namespace cinevol {

template <class F>
__global__ void ForEachPixelKernel(const F f, int width, int height) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y * blockDim.y + threadIdx.y;
  if (x < width && y < height) f(x, y);
}

struct CudaBackend {
  template <class T>
  using Buffer = cuda::DeviceBuffer<T>;
  // Host memory that Buffer::Download(T*) fills at full bus speed.
  template <class T>
  using HostBuffer = cuda::PinnedBuffer<T>;

  template <class F>
  static void ForEachPixel(int width, int height, const F& f) {
    const dim3 block(16, 8);
    const dim3 grid((width + block.x - 1) / block.x, (height + block.y - 1) / block.y);
    ForEachPixelKernel<<<grid, block, 0, cudaStreamPerThread>>>(f, width, height);
    CINEVOL_CUDA_CHECK_LAUNCH();
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
