// RAII device memory and error checks for the CUDA backends (renderer and
// denoiser). Included only by .cu files.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.h"
#include "device/frame_scratch.h"

namespace cinevol::cuda {

// Throws with the call site and CUDA's message; out-of-memory becomes
// ResourceExhausted so the service can answer RESOURCE_EXHAUSTED.
inline void Check(cudaError_t e, const char* what, const char* file, int line) {
  if (e == cudaSuccess) return;
  const std::string message = std::string(what) + " failed at " + file + ":" + std::to_string(line) + ": " +
                              cudaGetErrorString(e);
  if (e == cudaErrorMemoryAllocation) throw ResourceExhausted(message);
  throw std::runtime_error(message);
}

#define CINEVOL_CUDA_CHECK(call) ::cinevol::cuda::Check((call), #call, __FILE__, __LINE__)
// After a kernel launch: launch errors now, execution errors at the next sync.
#define CINEVOL_CUDA_CHECK_LAUNCH() ::cinevol::cuda::Check(cudaGetLastError(), "kernel launch", __FILE__, __LINE__)

// Copies `count` elements of device memory into a host vector, and waits.
template <class T>
std::vector<T> Download(const T* device, std::size_t count, cudaStream_t stream = cudaStreamPerThread) {
  std::vector<T> host(count);
  if (count == 0) return host;
  CINEVOL_CUDA_CHECK(cudaMemcpyAsync(host.data(), device, count * sizeof(T), cudaMemcpyDeviceToHost, stream));
  CINEVOL_CUDA_CHECK(cudaStreamSynchronize(stream));
  return host;
}

template <class T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(std::size_t count) { Resize(count); }
  ~DeviceBuffer() { Free(); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&& o) noexcept : data_(o.data_), count_(o.count_), capacity_(o.capacity_) {
    o.data_ = nullptr, o.count_ = o.capacity_ = 0;
  }
  DeviceBuffer& operator=(DeviceBuffer&& o) noexcept {
    std::swap(data_, o.data_);
    std::swap(count_, o.count_);
    std::swap(capacity_, o.capacity_);
    return *this;
  }

  // Contents are undefined after. Keeps the allocation for a size down to an
  // eighth of it: cudaFree and cudaMalloc wait for the whole GPU, every
  // session's work on it, and interactive frames (down to 0.375 of the
  // viewport's width and height, 0.14 of its pixels) change size each time a
  // view starts or stops moving.
  void Resize(std::size_t count) {
    if (count <= capacity_ && count * 8 >= capacity_) {
      count_ = count;
      return;
    }
    Free();
    if (count > 0) CINEVOL_CUDA_CHECK(cudaMalloc(&data_, count * sizeof(T)));
    count_ = capacity_ = count;
  }

  // Work is ordered on the calling thread's default stream (cudaStreamPerThread):
  // a session's renderer and denoiser run in order, sessions on other threads
  // overlap.
  void Upload(const T* host, std::size_t count, cudaStream_t stream = cudaStreamPerThread) {
    Resize(count);
    if (count > 0) CINEVOL_CUDA_CHECK(cudaMemcpyAsync(data_, host, count * sizeof(T), cudaMemcpyHostToDevice, stream));
  }
  void Upload(const std::vector<T>& host, cudaStream_t stream = cudaStreamPerThread) {
    Upload(host.data(), host.size(), stream);
  }

  // Copies every element into `host` (size() of them) and waits for the copy.
  // Into pinned memory (PinnedBuffer) the copy runs at full bus speed; into
  // pageable memory the driver stages it.
  void Download(T* host, cudaStream_t stream = cudaStreamPerThread) const {
    if (count_ == 0) return;
    CINEVOL_CUDA_CHECK(cudaMemcpyAsync(host, data_, count_ * sizeof(T), cudaMemcpyDeviceToHost, stream));
    CINEVOL_CUDA_CHECK(cudaStreamSynchronize(stream));
  }

  std::vector<T> Download(cudaStream_t stream = cudaStreamPerThread) const {
    return cuda::Download(data_, count_, stream);
  }

  void Zero(cudaStream_t stream = cudaStreamPerThread) {
    if (count_ > 0) CINEVOL_CUDA_CHECK(cudaMemsetAsync(data_, 0, count_ * sizeof(T), stream));
  }

  // Copies `count` elements already in device memory.
  void CopyFrom(const T* device, std::size_t count, cudaStream_t stream = cudaStreamPerThread) {
    Resize(count);
    if (count > 0)
      CINEVOL_CUDA_CHECK(cudaMemcpyAsync(data_, device, count * sizeof(T), cudaMemcpyDeviceToDevice, stream));
  }

  T* data() const { return data_; }
  std::size_t size() const { return count_; }
  std::size_t capacity() const { return capacity_; }  // elements allocated

 private:
  void Free() {
    if (data_) cudaFree(data_);
    data_ = nullptr;
    count_ = capacity_ = 0;
  }
  T* data_ = nullptr;
  std::size_t count_ = 0, capacity_ = 0;
};

// The frame's device buffer for `role` (frame_scratch.h): of its scope's
// set or, outside one, of this thread's on the current GPU. At least
// `bytes`, grown and never shrunk.
void* DeviceScratchBytes(Scratch role, std::size_t bytes);

// The same, as `count` elements of T.
template <class T>
T* DeviceScratch(Scratch role, std::size_t count) {
  return static_cast<T*>(DeviceScratchBytes(role, count * sizeof(T)));
}

// Page-locked host memory, the target of device-to-host copies that should
// not be staged through a driver buffer. Host code reads it like any memory.
template <class T>
class PinnedBuffer {
 public:
  PinnedBuffer() = default;
  ~PinnedBuffer() { Free(); }
  PinnedBuffer(const PinnedBuffer&) = delete;
  PinnedBuffer& operator=(const PinnedBuffer&) = delete;

  // Reallocates only to grow: pinning is slow, and a frame size that shrinks
  // and grows back (interactive resolution) should not pay it again.
  // Contents are undefined after.
  void Resize(std::size_t count) {
    if (count > capacity_) {
      Free();
      CINEVOL_CUDA_CHECK(cudaMallocHost(&data_, count * sizeof(T)));
      capacity_ = count;
    }
    count_ = count;
  }

  T* data() const { return data_; }
  std::size_t size() const { return count_; }

 private:
  void Free() {
    if (data_) cudaFreeHost(data_);
    data_ = nullptr;
    count_ = capacity_ = 0;
  }
  T* data_ = nullptr;
  std::size_t count_ = 0, capacity_ = 0;
};

}  // namespace cinevol::cuda
