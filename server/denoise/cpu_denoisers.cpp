// The denoisers instantiated for the CPU backend.
#include "device/cpu_backend.h"
#include "denoise/denoisers.h"

namespace cinevol {

std::unique_ptr<Denoiser> MakeCpuDenoiser(const DenoiserSettings& settings) {
  return MakeDenoiser<CpuBackend>(settings);
}

}  // namespace cinevol
