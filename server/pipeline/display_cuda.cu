// The pipeline's stages after the renderer (upsample, refine, display) on the GPU,
// after the renderer and denoiser on the same stream.
#include "device/cuda_backend.cuh"
#include "pipeline/display.h"
#include "pipeline/refine.h"
#include "pipeline/upsample.h"

namespace cinevol {

std::unique_ptr<Display> MakeCudaDisplay() { return std::make_unique<DisplayOn<CudaBackend>>(); }
std::unique_ptr<Upsampler> MakeCudaUpsampler() { return std::make_unique<UpsamplerOn<CudaBackend>>(); }
std::unique_ptr<Refiner> MakeCudaRefiner() { return std::make_unique<RefinerOn<CudaBackend>>(); }

}  // namespace cinevol
