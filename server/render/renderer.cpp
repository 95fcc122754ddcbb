// Choosing a backend.
#include "render/renderer.h"

#include "render/cpu_renderer.h"
#if CINEVOL_WITH_CUDA
#include "render/cuda_renderer.h"
#endif

namespace cinevol {

std::unique_ptr<Renderer> CreateRenderer(Backend backend, const RendererOptions& options) {
#if CINEVOL_WITH_CUDA
  if (Resolve(backend, "backend") == Backend::kCuda) return std::make_unique<CudaRenderer>(options);
#else
  Resolve(backend, "backend");  // throws for kCuda
#endif
  return std::make_unique<CpuRenderer>(options);
}

}  // namespace cinevol
