// The denoisers instantiated for the CUDA backend.
#include "denoise/backend_cuda.cuh"
#include "denoise/denoisers.h"

namespace cinevol {

std::unique_ptr<Denoiser> MakeCudaDenoiser(const DenoiserSettings& settings) {
  return MakeDenoiser<CudaBackend>(settings);
}

}  // namespace cinevol
