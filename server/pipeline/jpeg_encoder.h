// Where a streamed frame's JPEG is made, chosen once per process: from the
// display's planes on the host (libjpeg-turbo, in bands on idle compute
// threads: runtime/frame_encoding.h), or where the planes lie, on the GPU that
// rendered the frame, which copies only the bitstream back to the host: with
// cinevol's own coder (cuda_jpeg_encoder.cu, encode/jpeg_blocks.h) or with
// nvJPEG (loaded at run time: encode/nvjpeg_library.h).
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "core/ycc.h"
#include "device/device.h"
#include "encode/nvjpeg_library.h"

namespace cinevol {

enum class JpegEncoderKind { kAuto, kCpu, kCuda, kNvjpeg };

// "auto", "cpu", "cuda" or "nvjpeg"; throws InputError otherwise.
JpegEncoderKind ParseJpegEncoder(std::string_view name);
const char* ToString(JpegEncoderKind kind);

// The process's search for nvJPEG (FindNvjpeg), done once and logged once:
// which library was found, or why none was.
const NvjpegLookup& ProcessNvjpeg();

// The encoder for frames rendered on `backend` (kCpu or kCuda), logged:
// kAuto takes the GPU's own coder (kCuda) where the backend is CUDA, else the
// CPU; kCuda on the CPU backend, or kNvjpeg where nvJPEG does not load and
// start on this thread's GPU, throws InputError saying why (naming
// --jpeg-encoder).
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
  // quality in [1, 100] (clamped), at the planes' chroma subsampling. Empty
  // where the encoder gives the frame back (a frame denser than its room):
  // the caller then encodes the planes on the host.
  virtual std::vector<std::uint8_t> Encode(const YccPlanes& planes, int quality) = 0;
  // The last Encode's time from the planes being ready to the bitstream on the host.
  virtual double LastMilliseconds() const = 0;
};

// The GPU coder's most blocks in a restart interval: an interval's blocks sit
// in one thread block's shared memory (26 KB at 192).
inline constexpr int kMaxBlocksPerInterval = 192;

// How the GPU's own coder cuts and holds a frame.
struct CudaJpegSettings {
  // [6; kMaxBlocksPerInterval] 8x8 blocks a restart interval holds, in whole
  // MCUs (96: 16 MCUs at 4:2:0, 24 at 4:2:2, 32 at 4:4:4). Each interval is
  // one thread block, coded by one thread after the DCT: shorter intervals
  // finish sooner, but each costs a 2-byte marker, padding to a byte and DCs
  // coded afresh (96 blocks: +2.6% on a noisy 720p 4:2:0 frame;
  // tests/encode/jpeg_intervals_test.cpp).
  int blocks_per_interval = 96;
  // [8; jpeg::kMaxBytesPerBlock] bytes of device memory a block's coded data
  // may take in its interval's slot (2.7 MiB a 720p 4:2:0 frame at 128; a
  // 720p frame at quality 80 codes in about 2 bytes a block, white noise at
  // quality 100 in about 100). A frame an interval of which needs more is
  // given back to the host's encoder.
  int slot_bytes_per_block = 128;

  // The MCUs of an interval at `chroma` (3 to 6 blocks each).
  int mcus_per_interval(ChromaSubsampling chroma) const {
    const int blocks_per_mcu = chroma == ChromaSubsampling::k420 ? 6 : (chroma == ChromaSubsampling::k422 ? 4 : 3);
    return std::max(1, blocks_per_interval / blocks_per_mcu);
  }
};

#if CINEVOL_WITH_CUDA
// nvJPEG on the calling thread's GPU; throws std::runtime_error naming the
// nvJPEG call that failed.
std::unique_ptr<DeviceJpegEncoder> MakeNvjpegEncoder(std::shared_ptr<const NvjpegLibrary> library);
// The GPU's own coder on the calling thread's GPU and stream; the same bytes
// as EncodeJpegInIntervals (encode/jpeg_intervals.h) at
// settings.mcus_per_interval(chroma).
// Throws std::invalid_argument for settings out of range.
std::unique_ptr<DeviceJpegEncoder> MakeCudaJpegEncoder(const CudaJpegSettings& settings = {});
// Host planes copied to this thread's GPU and encoded there by one coder, in
// order: for tests and benches (an empty result: given back).
std::vector<std::vector<std::uint8_t>> EncodeOnGpu(const std::vector<ImageYcc8>& frames, int quality,
                                                   const CudaJpegSettings& settings);
std::vector<std::uint8_t> EncodeOnGpu(const ImageYcc8& planes, int quality, const CudaJpegSettings& settings);
#endif

}  // namespace cinevol
