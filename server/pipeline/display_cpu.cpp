// The pipeline's stages after the renderer (upsample, refine, display) on the CPU.
#include "core/ycc.h"
#include "device/cpu_backend.h"
#include "pipeline/display.h"
#include "pipeline/refine.h"
#include "pipeline/upsample.h"

namespace cinevol {

std::unique_ptr<Display> MakeCpuDisplay() { return std::make_unique<DisplayOn<CpuBackend>>(); }

ImageRgb8 ShownOnCpu(const ImageRgbF& radiance, float exposure) {
  DisplayInputs in;
  in.width = radiance.width;
  in.height = radiance.height;
  in.radiance = radiance.pixels.data();
  in.exposure = exposure;
  in.chroma = ChromaSubsampling::k444;
  return ToRgb(DisplayOn<CpuBackend>().Run(in));
}
std::unique_ptr<Upsampler> MakeCpuUpsampler() { return std::make_unique<UpsamplerOn<CpuBackend>>(); }
std::unique_ptr<Refiner> MakeCpuRefiner() { return std::make_unique<RefinerOn<CpuBackend>>(); }

}  // namespace cinevol
