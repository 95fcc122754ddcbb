// Backend choice, and GPU discovery in builds without CUDA (gpu.cu has the
// CUDA one).
#include "device/device.h"

#include <fmt/format.h>

#include "core/error.h"

namespace cinevol {

Backend ParseBackend(std::string_view name) {
  if (name == "auto") return Backend::kAuto;
  if (name == "cpu") return Backend::kCpu;
  if (name == "cuda") return Backend::kCuda;
  throw InputError(fmt::format("unknown backend '{}': use auto, cpu or cuda", name));
}

const char* ToString(Backend backend) {
  switch (backend) {
    case Backend::kCpu: return "cpu";
    case Backend::kCuda: return "cuda";
    default: return "auto";
  }
}

Backend Resolve(Backend choice, std::string_view what) {
  if (choice == Backend::kCpu) return Backend::kCpu;
  std::string why;
  const bool cuda = CudaAvailable(&why);
  if (choice == Backend::kCuda && !cuda) throw InputError(fmt::format("the CUDA {} is not available: {}", what, why));
  return cuda ? Backend::kCuda : Backend::kCpu;
}

GpuWait ParseGpuWait(std::string_view name) {
  if (name == "auto") return GpuWait::kAuto;
  if (name == "spin") return GpuWait::kSpin;
  if (name == "yield") return GpuWait::kYield;
  if (name == "block") return GpuWait::kBlock;
  throw InputError(fmt::format("unknown GPU wait '{}': use auto, spin, yield or block", name));
}

#if !CINEVOL_WITH_CUDA
void SetGpuWait(int index, GpuWait) { throw InputError(fmt::format("GPU {}: this build has no CUDA backend", index)); }

bool CudaAvailable(std::string* description) {
  if (description) *description = "this build has no CUDA backend (nvcc was not found)";
  return false;
}

std::vector<GpuInfo> ListGpus() { return {}; }

void UseGpu(int index) { throw InputError(fmt::format("GPU {}: this build has no CUDA backend", index)); }
#endif

}  // namespace cinevol
