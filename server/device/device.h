// Where work runs: the one backend enum, and GPU discovery. Renderers,
// denoisers and the display stage launch on the backend they are made for;
// the service asks here which GPUs there are and places sessions on them.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace cinevol {

// kAuto is a choice, resolved when something is made: CUDA where a usable
// GPU is present, else the CPU. What is made reports kCpu or kCuda.
enum class Backend { kAuto, kCpu, kCuda };

// "auto", "cpu" or "cuda"; throws InputError otherwise.
Backend ParseBackend(std::string_view name);
const char* ToString(Backend backend);

// kCpu or kCuda for a choice: kAuto resolved; kCuda without a usable GPU (or
// in a build without CUDA) throws InputError saying why, naming `what`.
Backend Resolve(Backend choice, std::string_view what);

// Whether a CUDA device can run kernels, and its name or the reason it can't.
bool CudaAvailable(std::string* description = nullptr);

struct GpuInfo {
  int index = 0;
  std::string name;
  std::size_t total_bytes = 0, free_bytes = 0;
};

// The GPUs this build can run on (compute capability 9.0 and newer); empty
// without a GPU or without CUDA.
std::vector<GpuInfo> ListGpus();

// Makes GPU `index` the calling thread's device: renderers and denoisers made
// and used on this thread allocate and run there.
void UseGpu(int index);

// How a host thread waits for its GPU work (a stream or event sync): kAuto is
// CUDA's choice (spin while the process has fewer GPU contexts than cores),
// kSpin burns its core and wakes at once, kYield spins but gives the core to
// other threads in between, kBlock sleeps until the GPU's interrupt wakes it
// (tens of microseconds later; no core spent).
enum class GpuWait { kAuto, kSpin, kYield, kBlock };

// "auto", "spin", "yield" or "block"; throws InputError otherwise.
GpuWait ParseGpuWait(std::string_view name);
// Sets how threads wait for GPU `index` (cudaSetDeviceFlags), for the whole
// process, whether or not its context has started.
void SetGpuWait(int index, GpuWait wait);

}  // namespace cinevol
