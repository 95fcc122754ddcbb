// This thread's device scratch (frame_scratch.h), per GPU.
#include <array>
#include <vector>

#include "device/cuda_buffer.h"
#include "device/frame_scratch.h"

namespace cinevol::cuda {

void* DeviceScratchBytes(Scratch role, std::size_t bytes) {
  using Buffers = std::array<DeviceBuffer<std::byte>, kScratchRoles>;
  thread_local std::vector<Buffers> per_gpu;
  int gpu = 0;
  CINEVOL_CUDA_CHECK(cudaGetDevice(&gpu));
  if (per_gpu.size() <= std::size_t(gpu)) per_gpu.resize(std::size_t(gpu) + 1);
  DeviceBuffer<std::byte>& buffer = per_gpu[std::size_t(gpu)][std::size_t(role)];
  // Grown only: cudaFree waits for the whole GPU, every session's work on it.
  if (buffer.capacity() < bytes) buffer.Resize(bytes);
  return buffer.data();
}

}  // namespace cinevol::cuda
