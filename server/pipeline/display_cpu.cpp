// The pipeline's stages after the renderer (upsample, refine, display) on the CPU.
#include "device/cpu_backend.h"
#include "pipeline/display.h"
#include "pipeline/refine.h"
#include "pipeline/upsample.h"

namespace cinevol {

std::unique_ptr<Display> MakeCpuDisplay() { return std::make_unique<DisplayOn<CpuBackend>>(); }
std::unique_ptr<Upsampler> MakeCpuUpsampler() { return std::make_unique<UpsamplerOn<CpuBackend>>(); }
std::unique_ptr<Refiner> MakeCpuRefiner() { return std::make_unique<RefinerOn<CpuBackend>>(); }

}  // namespace cinevol
