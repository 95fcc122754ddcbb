// Where a streamed frame's JPEG is made, chosen once per process: from the
// display's planes on the host (libjpeg-turbo, in bands on idle compute
// threads: runtime/frame_encoding.h), or where the planes lie, on the GPU that
// rendered the frame (nvJPEG, loaded at run time: encode/nvjpeg_library.h),
// which copies only the bitstream back to the host.
#pragma once

#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "core/ycc.h"
#include "device/device.h"
#include "encode/nvjpeg_library.h"

namespace cinevol {

enum class JpegEncoderKind { kAuto, kCpu, kNvjpeg };

// "auto", "cpu" or "nvjpeg"; throws InputError otherwise.
JpegEncoderKind ParseJpegEncoder(std::string_view name);
const char* ToString(JpegEncoderKind kind);

// The process's search for nvJPEG (FindNvjpeg), done once and logged once:
// which library was found, or why none was.
const NvjpegLookup& ProcessNvjpeg();

// kCpu or kNvjpeg for frames rendered on `backend` (kCpu or kCuda), logged:
// kAuto takes nvJPEG where the backend is CUDA and the library loads and
// starts on this thread's GPU, else the CPU; kNvjpeg where it cannot throws
// InputError saying why (naming --jpeg-encoder).
JpegEncoderKind ChooseJpegEncoder(JpegEncoderKind requested, Backend backend,
                                  const NvjpegLookup& nvjpeg = ProcessNvjpeg());

// A frame encoded on the device.
struct EncodedJpeg {
  int width = 0, height = 0;
  std::vector<std::uint8_t> bytes;
};

// Encodes YCbCr planes in device memory where they lie, on the calling
// thread's stream; only the bitstream comes back to the host.
class DeviceJpegEncoder {
 public:
  virtual ~DeviceJpegEncoder() = default;
  // quality in [1, 100] (clamped), at the planes' chroma subsampling.
  virtual std::vector<std::uint8_t> Encode(const YccPlanes& planes, int quality) = 0;
  // The last Encode's time from the planes being ready to the bitstream on the host.
  virtual double LastMilliseconds() const = 0;
};

#if CINEVOL_WITH_CUDA
// nvJPEG on the calling thread's GPU; throws std::runtime_error naming the
// nvJPEG call that failed.
std::unique_ptr<DeviceJpegEncoder> MakeNvjpegEncoder(std::shared_ptr<const NvjpegLibrary> library);
#endif

}  // namespace cinevol
