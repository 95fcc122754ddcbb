// A prepared volume's voxels in a GPU's memory.
#include "device/cuda_buffer.h"
#include "render/prepared_volume.h"

namespace cinevol {
namespace {

using cuda::DeviceBuffer;

// Makes `gpu` the calling thread's device for a while: the last owner of a
// copy may let it go on any thread (a session ending on a gRPC thread).
class OnGpu {
 public:
  explicit OnGpu(int gpu) {
    CINEVOL_CUDA_CHECK(cudaGetDevice(&previous_));
    CINEVOL_CUDA_CHECK(cudaSetDevice(gpu));
  }
  ~OnGpu() { cudaSetDevice(previous_); }
  OnGpu(const OnGpu&) = delete;
  OnGpu& operator=(const OnGpu&) = delete;

 private:
  int previous_ = 0;
};

}  // namespace

std::shared_ptr<const std::uint16_t> UploadVoxels(const std::uint16_t* host, std::size_t count, int gpu) {
  OnGpu on(gpu);
  auto buffer = std::make_shared<DeviceBuffer<std::uint16_t>>();
  buffer->Upload(host, count);
  // Renderers on other threads (other streams) read it next.
  CINEVOL_CUDA_CHECK(cudaStreamSynchronize(cudaStreamPerThread));
  const std::uint16_t* voxels = buffer->data();
  return std::shared_ptr<const std::uint16_t>(voxels, [buffer = std::move(buffer), gpu](const std::uint16_t*) mutable {
    // cudaFree waits for kernels still reading it. Errors are ignored: a
    // deleter must not throw, and a lost device leaves nothing to free.
    int previous = 0;
    cudaGetDevice(&previous);
    cudaSetDevice(gpu);
    buffer.reset();
    cudaSetDevice(previous);
  });
}

}  // namespace cinevol
