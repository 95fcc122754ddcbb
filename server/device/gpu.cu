// GPU discovery through the CUDA runtime.
#include <cuda_runtime.h>

#include "device/cuda_buffer.h"
#include "device/device.h"

namespace cinevol {

bool CudaAvailable(std::string* description) {
  int count = 0;
  // Without a driver or GPU this fails (e.g. "CUDA driver version is
  // insufficient"): any error means no GPU.
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e != cudaSuccess || count == 0) {
    if (description) *description = e != cudaSuccess ? cudaGetErrorString(e) : "no CUDA device found";
    cudaGetLastError();  // clear the sticky error
    return false;
  }
  cudaDeviceProp prop;
  if (cudaGetDeviceProperties(&prop, 0) != cudaSuccess) {
    if (description) *description = "cannot query CUDA device 0";
    return false;
  }
  if (prop.major < 9) {
    if (description) {
      *description = std::string(prop.name) + " has compute capability " + std::to_string(prop.major) + "." +
                     std::to_string(prop.minor) + "; this build targets 9.0 and newer";
    }
    return false;
  }
  if (description) *description = prop.name;
  return true;
}

std::vector<GpuInfo> ListGpus() {
  std::vector<GpuInfo> gpus;
  if (!CudaAvailable()) return gpus;
  int count = 0;
  CINEVOL_CUDA_CHECK(cudaGetDeviceCount(&count));
  int current = 0;
  CINEVOL_CUDA_CHECK(cudaGetDevice(&current));
  for (int i = 0; i < count; ++i) {
    cudaDeviceProp prop;
    CINEVOL_CUDA_CHECK(cudaGetDeviceProperties(&prop, i));
    if (prop.major < 9) continue;
    GpuInfo info{i, prop.name, prop.totalGlobalMem, 0};
    CINEVOL_CUDA_CHECK(cudaSetDevice(i));
    CINEVOL_CUDA_CHECK(cudaMemGetInfo(&info.free_bytes, &info.total_bytes));
    gpus.push_back(info);
  }
  CINEVOL_CUDA_CHECK(cudaSetDevice(current));
  return gpus;
}

void UseGpu(int index) { CINEVOL_CUDA_CHECK(cudaSetDevice(index)); }

void SetGpuWait(int index, GpuWait wait) {
  constexpr unsigned kFlags[] = {cudaDeviceScheduleAuto, cudaDeviceScheduleSpin, cudaDeviceScheduleYield,
                                 cudaDeviceScheduleBlockingSync};
  int current = 0;
  CINEVOL_CUDA_CHECK(cudaGetDevice(&current));
  CINEVOL_CUDA_CHECK(cudaSetDevice(index));
  CINEVOL_CUDA_CHECK(cudaSetDeviceFlags(kFlags[static_cast<int>(wait)]));
  CINEVOL_CUDA_CHECK(cudaSetDevice(current));
}

}  // namespace cinevol
