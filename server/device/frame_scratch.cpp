// This thread's host scratch (frame_scratch.h); frame_scratch.cu has the GPU's.
#include "device/frame_scratch.h"

#include <array>
#include <vector>

namespace cinevol {

void* HostScratch(Scratch role, std::size_t bytes) {
  // operator new's memory: aligned for any fundamental type (16 bytes here).
  thread_local std::array<std::vector<std::byte>, kScratchRoles> buffers;
  std::vector<std::byte>& buffer = buffers[std::size_t(role)];
  if (buffer.size() < bytes) buffer = std::vector<std::byte>(bytes);
  return buffer.data();
}

#ifndef CINEVOL_WITH_CUDA
// Without CUDA no frame runs on a GPU (frame_scratch.cu has the pool).
FrameScratchScope::FrameScratchScope(std::size_t pixels)
    : pixels_(pixels), pool_(nullptr), set_(nullptr), previous_(nullptr) {}
FrameScratchScope::~FrameScratchScope() = default;
#endif

}  // namespace cinevol
