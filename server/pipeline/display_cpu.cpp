// The display stage on the CPU.
#include "denoise/backend_cpu.h"
#include "pipeline/display.h"

namespace cinevol {

std::unique_ptr<Display> MakeCpuDisplay() { return std::make_unique<DisplayOn<CpuBackend>>(); }

}  // namespace cinevol
