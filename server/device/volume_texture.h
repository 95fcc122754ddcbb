// A 16-bit volume as a CUDA 3D texture: the texture unit clamps to the edge
// and interpolates trilinearly in one fetch, where reading the voxels takes
// eight dependent loads and the index arithmetic (the path tracer is
// latency-bound; docs/performance.md). Its weights have 8 fractional bits, so
// the interpolated value differs from exact trilinear by at most 1/256 of the
// step between neighbouring voxels. Included only by .cu files.
#pragma once

#include <cuda_runtime.h>

#include <cstdint>

#include "core/vec.h"
#include "device/cuda_buffer.h"

namespace cinevol::cuda {

class VolumeTexture {
 public:
  VolumeTexture() = default;
  ~VolumeTexture() { Free(); }
  VolumeTexture(const VolumeTexture&) = delete;
  VolumeTexture& operator=(const VolumeTexture&) = delete;

  // Copies `voxels` (x fastest) into a 3D array on the current GPU. Returns
  // false, holding nothing, where the volume exceeds the GPU's 3D texture
  // size: callers then read the voxels from a buffer instead.
  bool Upload(const std::uint16_t* voxels, Vec3i dims, cudaStream_t stream) {
    Free();
    int device = 0, max_x = 0, max_y = 0, max_z = 0;
    CINEVOL_CUDA_CHECK(cudaGetDevice(&device));
    CINEVOL_CUDA_CHECK(cudaDeviceGetAttribute(&max_x, cudaDevAttrMaxTexture3DWidth, device));
    CINEVOL_CUDA_CHECK(cudaDeviceGetAttribute(&max_y, cudaDevAttrMaxTexture3DHeight, device));
    CINEVOL_CUDA_CHECK(cudaDeviceGetAttribute(&max_z, cudaDevAttrMaxTexture3DDepth, device));
    if (dims.x > max_x || dims.y > max_y || dims.z > max_z) return false;

    const cudaExtent extent = make_cudaExtent(dims.x, dims.y, dims.z);
    const cudaChannelFormatDesc format = cudaCreateChannelDesc<std::uint16_t>();
    CINEVOL_CUDA_CHECK(cudaMalloc3DArray(&array_, &format, extent));
    cudaMemcpy3DParms copy{};
    copy.srcPtr = make_cudaPitchedPtr(const_cast<std::uint16_t*>(voxels), dims.x * sizeof(std::uint16_t), dims.x,
                                      dims.y);
    copy.dstArray = array_;
    copy.extent = extent;
    copy.kind = cudaMemcpyHostToDevice;
    CINEVOL_CUDA_CHECK(cudaMemcpy3DAsync(&copy, stream));

    cudaResourceDesc resource{};
    resource.resType = cudaResourceTypeArray;
    resource.res.array.array = array_;
    cudaTextureDesc sampling{};
    for (auto& mode : sampling.addressMode) mode = cudaAddressModeClamp;
    sampling.filterMode = cudaFilterModeLinear;
    sampling.readMode = cudaReadModeNormalizedFloat;  // stored / 65535
    sampling.normalizedCoords = 0;                    // texel centres at i + 0.5
    CINEVOL_CUDA_CHECK(cudaCreateTextureObject(&texture_, &resource, &sampling, nullptr));
    bytes_ = std::size_t(dims.x) * dims.y * dims.z * sizeof(std::uint16_t);
    return true;
  }

  cudaTextureObject_t handle() const { return texture_; }
  std::size_t bytes() const { return bytes_; }

 private:
  void Free() {
    if (texture_) cudaDestroyTextureObject(texture_);
    if (array_) cudaFreeArray(array_);
    texture_ = 0;
    array_ = nullptr;
    bytes_ = 0;
  }

  cudaArray_t array_ = nullptr;
  cudaTextureObject_t texture_ = 0;
  std::size_t bytes_ = 0;
};

}  // namespace cinevol::cuda
