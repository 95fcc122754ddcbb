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

}  // namespace cinevol
