// The pipeline's stages after the renderer (upsample, refine, display) on the CPU.
#include "core/ycc.h"
#include "device/cpu_backend.h"
#include "pipeline/display.h"
#include "pipeline/tone_map_table.h"
#include "pipeline/refine.h"
#include "pipeline/upsample.h"

namespace cinevol {

namespace {

using CpuDisplay = DisplayOn<CpuBackend, TableToneMap>;

}  // namespace

std::unique_ptr<Display> MakeCpuDisplay() { return std::make_unique<CpuDisplay>(TableToneMap{&ToneMapTable::Get()}); }

ImageRgb8 ShownOnCpu(const ImageRgbF& radiance, float exposure) {
  DisplayInputs in;
  in.width = radiance.width;
  in.height = radiance.height;
  in.radiance = radiance.pixels.data();
  in.exposure = exposure;
  in.chroma = ChromaSubsampling::k444;
  return ToRgb(CpuDisplay(TableToneMap{&ToneMapTable::Get()}).Run(in));
}
std::unique_ptr<Upsampler> MakeCpuUpsampler() { return std::make_unique<UpsamplerOn<CpuBackend>>(); }
std::unique_ptr<Refiner> MakeCpuRefiner() { return std::make_unique<RefinerOn<CpuBackend>>(); }

}  // namespace cinevol
