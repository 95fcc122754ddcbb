// Device buffers keep their memory across the sizes an interactive view's
// frames take: cudaFree and cudaMalloc wait for the whole GPU, every
// session's work on it, each time a view starts or stops moving.
#include <gtest/gtest.h>

#if CINEVOL_WITH_CUDA
#include <numeric>
#include <vector>

#include "device/cuda_buffer.h"
#include "support/gpu.h"

namespace cinevol {
namespace {

TEST(CudaBuffer, KeepsItsMemoryForFramesDownToAnEighthOfIt) {
  CINEVOL_REQUIRE_CUDA();
  cuda::DeviceBuffer<float> buffer(1000);
  float* const memory = buffer.data();
  buffer.Resize(141);  // a frame at 0.375 of the width and height
  EXPECT_EQ(buffer.data(), memory);
  EXPECT_EQ(buffer.size(), 141u);
  buffer.Resize(1000);  // full size again
  EXPECT_EQ(buffer.data(), memory);
  EXPECT_EQ(buffer.size(), 1000u);
  buffer.Resize(124);  // a much smaller viewport: the memory goes back
  EXPECT_EQ(buffer.capacity(), 124u);
  buffer.Resize(1001);  // a larger one than any before
  EXPECT_EQ(buffer.capacity(), 1001u);
  buffer.Resize(0);
  EXPECT_EQ(buffer.data(), nullptr);
}

TEST(CudaBuffer, CopiesTheSizeInUseNotItsMemory) {
  CINEVOL_REQUIRE_CUDA();
  std::vector<int> values(1000);
  std::iota(values.begin(), values.end(), 0);
  cuda::DeviceBuffer<int> buffer;
  buffer.Upload(values);
  buffer.Upload(values.data(), 300);
  EXPECT_EQ(buffer.capacity(), 1000u);
  EXPECT_EQ(buffer.Download(), std::vector<int>(values.begin(), values.begin() + 300));
}

}  // namespace
}  // namespace cinevol
#endif
