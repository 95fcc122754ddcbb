// The denoisers instantiated for the CUDA backend.
#include "device/cuda_backend.cuh"
#include "denoise/denoisers.h"

namespace cinevol {

std::unique_ptr<Denoiser> MakeCudaDenoiser(const DenoiserSettings& settings) {
  return MakeDenoiser<CudaBackend>(settings);
}

}  // namespace cinevol
