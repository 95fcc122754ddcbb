// JPEG on the GPU that rendered the frame, from the display's planes where
// they lie, with encode/jpeg_blocks.h's coder: the same bytes as the CPU's
// EncodeJpegInIntervals. Each restart interval of MCUs is one thread block,
// whose threads quantise a block each into shared memory and whose first
// thread then codes the interval into a slot of its own; one more block
// places the slots behind RST markers, and a warp an interval copies them
// straight into pinned host memory. Only the
// JPEG crosses the bus, the host only copies it out, and every buffer is kept
// from frame to frame: no allocation, no synchronisation but the frame's own.
#include <cub/block/block_scan.cuh>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <tuple>

#include "device/cuda_buffer.h"
#include "encode/jpeg_intervals.h"
#include "encode/jpeg_tables.h"
#include "pipeline/jpeg_encoder.h"

namespace cinevol {
namespace {

constexpr int kJoinThreads = 1024;

// What the join leaves for the host, in pinned memory.
struct JoinResult {
  int length;    // the coded data's bytes, markers included
  int overflow;  // 1: an interval outgrew its slot; nothing was joined
};

// A block of shared memory per interval: each block's zigzag coefficients,
// then their non-zero masks, then whether each is padding.
struct IntervalScratch {
  std::int16_t (*zigzag)[jpeg::kBlockSamples];
  std::uint64_t* nonzero;
  bool* padding;

  static constexpr std::size_t BytesPerBlock() { return sizeof(std::int16_t) * jpeg::kBlockSamples + 8 + 1; }
  __device__ static IntervalScratch In(unsigned char* shared, int capacity) {
    IntervalScratch s;
    s.zigzag = reinterpret_cast<std::int16_t(*)[jpeg::kBlockSamples]>(shared);
    s.nonzero = reinterpret_cast<std::uint64_t*>(shared + sizeof(std::int16_t) * jpeg::kBlockSamples * capacity);
    s.padding = reinterpret_cast<bool*>(s.nonzero + capacity);
    return s;
  }
};

// One interval a thread block: every thread quantises blocks, then thread 0
// codes them (the coder is serial within an interval) into the slot.
__global__ void CodeIntervalsKernel(jpeg::FramePlanes planes, jpeg::McuLayout layout, int mcus_per_interval,
                                    const jpeg::JpegTables* tables, std::uint8_t* slots, int slot_capacity,
                                    int* lengths) {
  extern __shared__ __align__(16) unsigned char shared[];
  const int per_mcu = layout.blocks_per_mcu();
  const int first_mcu = blockIdx.x * mcus_per_interval;
  const int mcus = min(mcus_per_interval, layout.mcus() - first_mcu);
  const int blocks = mcus * per_mcu;
  const IntervalScratch s = IntervalScratch::In(shared, mcus_per_interval * per_mcu);
  for (int b = threadIdx.x; b < blocks; b += blockDim.x) {
    const jpeg::BlockPosition at = jpeg::PositionOf(layout, first_mcu + b / per_mcu, b % per_mcu);
    s.padding[b] = at.padding;
    if (!at.padding) {
      s.nonzero[b] = jpeg::QuantizeBlock(jpeg::PlaneOf(planes, at.component), at.bx, at.by,
                                         tables->divisor[at.component == 0 ? 0 : 1], s.zigzag[b]);
    }
  }
  __syncthreads();
  if (threadIdx.x != 0) return;
  jpeg::BitSink sink(slots + std::size_t(blockIdx.x) * slot_capacity, slot_capacity);
  auto block = [&](int b) {
    return s.padding[b] ? jpeg::QuantizedBlock{} : jpeg::QuantizedBlock{s.zigzag[b], s.nonzero[b]};
  };
  jpeg::CodeInterval(layout, mcus, *tables, block, sink);
  lengths[blockIdx.x] = sink.length();
}

// One thread block: each interval's offset (its data after those before and
// an RST marker between each two), and whether the frame can be joined:
// where an interval outgrew its slot, or the data does not fit
// `out_capacity`, nothing is copied and the result says what happened.
__global__ void OffsetIntervalsKernel(const int* lengths, int intervals, int slot_capacity, int out_capacity,
                                      int* offsets, int* join, JoinResult* result) {
  using Scan = cub::BlockScan<int, kJoinThreads>;
  __shared__ typename Scan::TempStorage scan_storage;
  __shared__ int carry;
  if (threadIdx.x == 0) carry = 0;
  bool overflow = false;
  for (int first = 0; first < intervals; first += kJoinThreads) {
    const int i = first + threadIdx.x;
    const int length = i < intervals ? lengths[i] : 0;
    overflow |= length > slot_capacity;
    const int bytes = i < intervals ? length + (i > 0 ? 2 : 0) : 0;
    int offset = 0, chunk = 0;
    __syncthreads();  // carry written
    Scan(scan_storage).ExclusiveSum(bytes, offset, chunk);
    if (i < intervals) offsets[i] = carry + offset + (i > 0 ? 2 : 0);
    __syncthreads();  // everyone read carry
    if (threadIdx.x == 0) carry += chunk;
  }
  overflow = __syncthreads_or(overflow);
  if (threadIdx.x == 0) {
    *join = !overflow && carry <= out_capacity;
    *result = {carry, overflow ? 1 : 0};
  }
}

// A warp an interval, over as many blocks as the intervals fill: its bytes,
// and the RST marker before it, copied to `out` (pinned host memory). One
// block alone took 87 us of a 4K frame (Nsight Compute's clocks) writing
// across the bus.
__global__ void CopyIntervalsKernel(const std::uint8_t* slots, int slot_capacity, const int* lengths,
                                    const int* offsets, int intervals, const int* join, std::uint8_t* out) {
  if (!*join) return;
  const int lane = threadIdx.x % 32;
  const int i = (blockIdx.x * blockDim.x + threadIdx.x) / 32;
  if (i >= intervals) return;
  const int offset = offsets[i], length = lengths[i];
  const std::uint8_t* slot = slots + std::size_t(i) * slot_capacity;
  for (int j = lane; j < length; j += 32) out[offset + j] = slot[j];
  if (i > 0 && lane == 0) {
    out[offset - 2] = 0xFF;
    out[offset - 1] = jpeg::RestartMarker(i - 1);
  }
}

jpeg::FramePlanes PlanesOf(const YccPlanes& p) {
  const int cw = ChromaWidth(p.width, p.chroma), ch = ChromaHeight(p.height, p.chroma);
  return {{{p.y, p.width, p.height}, {p.cb, cw, ch}, {p.cr, cw, ch}}};
}

class CudaJpegEncoder final : public DeviceJpegEncoder {
 public:
  explicit CudaJpegEncoder(const CudaJpegSettings& settings) : settings_(settings) {
    CINEVOL_CUDA_CHECK(cudaEventCreate(&start_));
    CINEVOL_CUDA_CHECK(cudaEventCreate(&stop_));
    result_.Resize(1);
    join_.Resize(1);
  }
  ~CudaJpegEncoder() override {
    cudaEventDestroy(start_);
    cudaEventDestroy(stop_);
  }

  std::vector<std::uint8_t> Encode(const YccPlanes& planes, int quality) override {
    quality = std::clamp(quality, 1, 100);
    const jpeg::McuLayout layout = jpeg::McuLayout::Of(planes.width, planes.height, planes.chroma);
    const int mcus_per_interval = settings_.mcus_per_interval(planes.chroma);
    const int intervals = (layout.mcus() + mcus_per_interval - 1) / mcus_per_interval;
    const int blocks_per_interval = mcus_per_interval * layout.blocks_per_mcu();
    const int slot_capacity = blocks_per_interval * settings_.slot_bytes_per_block;
    slots_.Resize(std::size_t(intervals) * slot_capacity);
    lengths_.Resize(std::size_t(intervals));
    offsets_.Resize(std::size_t(intervals));
    if (out_.size() == 0) out_.Resize(std::size_t(layout.mcus()) * layout.blocks_per_mcu() * kFirstBytesPerBlock);

    const cudaStream_t stream = cudaStreamPerThread;
    CINEVOL_CUDA_CHECK(cudaEventRecord(start_, stream));
    const int threads = std::min(1024, (blocks_per_interval + 31) / 32 * 32);
    const std::size_t shared = std::size_t(blocks_per_interval) * IntervalScratch::BytesPerBlock();
    CodeIntervalsKernel<<<intervals, threads, shared, stream>>>(PlanesOf(planes), layout, mcus_per_interval,
                                                                 Tables(quality), slots_.data(), slot_capacity,
                                                                 lengths_.data());
    CINEVOL_CUDA_CHECK_LAUNCH();
    JoinResult joined = Join(intervals, slot_capacity);
    if (joined.overflow) return {};  // the caller encodes the planes on the host
    if (joined.length > int(out_.size())) {  // a larger frame than any before: room, and join again
      out_.Resize(std::size_t(joined.length) * 2);
      joined = Join(intervals, slot_capacity);
    }
    return Assemble(planes, quality, joined.length);
  }

  double LastMilliseconds() const override { return last_ms_; }

 private:
  // The host's first guess of a frame's size, grown when a frame needs more.
  static constexpr int kFirstBytesPerBlock = 16;

  // Launches the join, waits for the frame, reads what it left.
  JoinResult Join(int intervals, int slot_capacity) {
    const cudaStream_t stream = cudaStreamPerThread;
    OffsetIntervalsKernel<<<1, kJoinThreads, 0, stream>>>(lengths_.data(), intervals, slot_capacity,
                                                          int(out_.size()), offsets_.data(), join_.data(),
                                                          result_.data());
    CINEVOL_CUDA_CHECK_LAUNCH();
    constexpr int kCopyThreads = 256;  // 8 intervals a block
    const int copy_blocks = (intervals + kCopyThreads / 32 - 1) / (kCopyThreads / 32);
    CopyIntervalsKernel<<<copy_blocks, kCopyThreads, 0, stream>>>(slots_.data(), slot_capacity, lengths_.data(),
                                                                  offsets_.data(), intervals, join_.data(),
                                                                  out_.data());
    CINEVOL_CUDA_CHECK_LAUNCH();
    CINEVOL_CUDA_CHECK(cudaEventRecord(stop_, stream));
    CINEVOL_CUDA_CHECK(cudaEventSynchronize(stop_));
    float ms = 0;
    CINEVOL_CUDA_CHECK(cudaEventElapsedTime(&ms, start_, stop_));
    last_ms_ = ms;
    return *result_.data();
  }

  std::vector<std::uint8_t> Assemble(const YccPlanes& planes, int quality, int length) {
    HeaderKey key{planes.width, planes.height, planes.chroma, quality};
    auto it = headers_.find(key);
    if (it == headers_.end()) {
      it = headers_.emplace(key, jpeg::FrameHeader(planes.width, planes.height, planes.chroma, quality,
                                                   settings_.mcus_per_interval(planes.chroma))).first;
    }
    std::vector<std::uint8_t> jpeg;
    jpeg.reserve(it->second.size() + std::size_t(length) + 2);
    jpeg.insert(jpeg.end(), it->second.begin(), it->second.end());
    jpeg.insert(jpeg.end(), out_.data(), out_.data() + length);
    jpeg.insert(jpeg.end(), std::begin(jpeg::kEndOfImage), std::end(jpeg::kEndOfImage));
    return jpeg;
  }

  // The coder's tables for `quality` on this GPU, uploaded on first use.
  const jpeg::JpegTables* Tables(int quality) {
    cuda::DeviceBuffer<jpeg::JpegTables>& tables = tables_[quality];
    if (tables.size() == 0) tables.Upload(&jpeg::TablesFor(quality).coding, 1);
    return tables.data();
  }

  struct HeaderKey {
    int width, height;
    ChromaSubsampling chroma;
    int quality;
    bool operator<(const HeaderKey& o) const {
      return std::tie(width, height, chroma, quality) < std::tie(o.width, o.height, o.chroma, o.quality);
    }
  };

  const CudaJpegSettings settings_;
  std::map<int, cuda::DeviceBuffer<jpeg::JpegTables>> tables_;  // by quality: a session uses two
  std::map<HeaderKey, std::vector<std::uint8_t>> headers_;
  cuda::DeviceBuffer<std::uint8_t> slots_;  // each interval's coded data, at slot_capacity apart
  cuda::DeviceBuffer<int> lengths_, offsets_;
  cuda::DeviceBuffer<int> join_;            // 1: the offsets' kernel found the frame fits; the copy goes ahead
  cuda::PinnedBuffer<std::uint8_t> out_;    // the joined data, written by the GPU
  cuda::PinnedBuffer<JoinResult> result_;
  cudaEvent_t start_ = nullptr, stop_ = nullptr;
  double last_ms_ = 0;
};

}  // namespace

namespace {

void CheckCudaJpegSettings(const CudaJpegSettings& s) {
  if (s.blocks_per_interval < 6 || s.blocks_per_interval > kMaxBlocksPerInterval) {
    throw std::invalid_argument("CudaJpegSettings::blocks_per_interval out of [6, 192]");
  }
  if (s.slot_bytes_per_block < 8 || s.slot_bytes_per_block > jpeg::kMaxBytesPerBlock) {
    throw std::invalid_argument("CudaJpegSettings::slot_bytes_per_block out of range");
  }
}

}  // namespace

std::unique_ptr<DeviceJpegEncoder> MakeCudaJpegEncoder(const CudaJpegSettings& settings) {
  CheckCudaJpegSettings(settings);
  return std::make_unique<CudaJpegEncoder>(settings);
}

std::vector<std::vector<std::uint8_t>> EncodeOnGpu(const std::vector<ImageYcc8>& frames, int quality,
                                                   const CudaJpegSettings& settings) {
  const std::unique_ptr<DeviceJpegEncoder> encoder = MakeCudaJpegEncoder(settings);
  cuda::DeviceBuffer<std::uint8_t> planes;
  std::vector<std::vector<std::uint8_t>> encoded;
  for (const ImageYcc8& frame : frames) {
    planes.Upload(frame.data.get(), YccBytes(frame.width, frame.height, frame.chroma));
    encoded.push_back(encoder->Encode(YccPlanes::Of(planes.data(), frame.width, frame.height, frame.chroma), quality));
  }
  return encoded;
}

std::vector<std::uint8_t> EncodeOnGpu(const ImageYcc8& planes, int quality, const CudaJpegSettings& settings) {
  return EncodeOnGpu(std::vector<ImageYcc8>{planes}, quality, settings).front();
}

}  // namespace cinevol
