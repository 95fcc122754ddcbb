// Choosing a backend.
#include "render/renderer.h"

#include <fmt/format.h>

#include "core/error.h"
#include "render/cpu_renderer.h"
#if CINEVOL_WITH_CUDA
#include "render/cuda_renderer.h"
#endif

namespace cinevol {

Backend ParseBackend(std::string_view name) {
  if (name == "auto") return Backend::kAuto;
  if (name == "cpu") return Backend::kCpu;
  if (name == "cuda") return Backend::kCuda;
  throw InputError(fmt::format("unknown backend '{}': use auto, cpu or cuda", name));
}

#if !CINEVOL_WITH_CUDA
bool CudaAvailable(std::string* description) {
  if (description) *description = "this build has no CUDA backend (nvcc was not found)";
  return false;
}

std::vector<GpuInfo> ListGpus() { return {}; }

void UseGpu(int index) { throw InputError(fmt::format("GPU {}: this build has no CUDA backend", index)); }
#endif

std::unique_ptr<Renderer> CreateRenderer(Backend backend, const RendererOptions& options) {
  if (backend == Backend::kCpu) return std::make_unique<CpuRenderer>(options);
  std::string why;
  const bool cuda = CudaAvailable(&why);
  if (backend == Backend::kCuda && !cuda) throw InputError("the CUDA backend is not available: " + why);
#if CINEVOL_WITH_CUDA
  if (cuda) return std::make_unique<CudaRenderer>(options);
#endif
  return std::make_unique<CpuRenderer>(options);
}

}  // namespace cinevol
