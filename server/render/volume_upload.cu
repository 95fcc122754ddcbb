// A prepared volume's voxels, and a segmentation's labels, in a GPU's memory.
#include "device/cuda_buffer.h"
#include "device/volume_texture.h"
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

std::shared_ptr<const GpuVoxels> UploadVoxels(const PreparedVolume& prepared, int gpu, bool texture) {
  OnGpu on(gpu);
  struct Owned {
    DeviceBuffer<std::uint16_t> buffer;
    cuda::VolumeTexture texture;
    GpuVoxels view;
  };
  auto owned = std::make_shared<Owned>();
  // Once: as a texture where one fits (every lookup then reads it), else as a buffer.
  if (!texture || !owned->texture.Upload(prepared.voxels(), prepared.volume().dims(), cudaStreamPerThread)) {
    owned->buffer.Upload(prepared.voxels(), prepared.volume().voxel_count());
  }
  // Renderers on other threads (other streams) read it next.
  CINEVOL_CUDA_CHECK(cudaStreamSynchronize(cudaStreamPerThread));
  owned->view = {owned->buffer.data(), owned->texture.handle(),
                 owned->buffer.size() * sizeof(std::uint16_t) + owned->texture.bytes()};
  const GpuVoxels* view = &owned->view;
  return std::shared_ptr<const GpuVoxels>(view, [owned = std::move(owned), gpu](const GpuVoxels*) mutable {
    // cudaFree waits for kernels still reading it. Errors are ignored: a
    // deleter must not throw, and a lost device leaves nothing to free.
    int previous = 0;
    cudaGetDevice(&previous);
    cudaSetDevice(gpu);
    owned.reset();
    cudaSetDevice(previous);
  });
}

namespace {

// `values` in a buffer on `gpu`; the pointer frees it there (from any thread).
template <class T>
std::shared_ptr<const T> UploadBuffer(const std::vector<T>& values, int gpu) {
  OnGpu on(gpu);
  auto owned = std::make_shared<DeviceBuffer<T>>();
  owned->Upload(values);
  CINEVOL_CUDA_CHECK(cudaStreamSynchronize(cudaStreamPerThread));  // read next on other streams
  const T* data = owned->data();  // before the deleter takes `owned`
  return std::shared_ptr<const T>(data, [owned = std::move(owned), gpu](const T*) mutable {
    int previous = 0;  // as for the voxels: free it on its GPU, ignore errors
    cudaGetDevice(&previous);
    cudaSetDevice(gpu);
    owned.reset();
    cudaSetDevice(previous);
  });
}

}  // namespace

std::shared_ptr<const std::uint16_t> UploadLabels(const LabelVolume& labels, int gpu) {
  return UploadBuffer(labels.labels, gpu);
}

std::shared_ptr<const float> UploadMajorants(const std::vector<float>& majorants, int gpu) {
  return UploadBuffer(majorants, gpu);
}

}  // namespace cinevol
