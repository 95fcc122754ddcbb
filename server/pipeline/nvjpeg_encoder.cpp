// nvJPEG behind DeviceJpegEncoder: a handle, an encoder state and its
// parameters per pipeline, on the pipeline's GPU and its thread's stream
// (cudaStreamPerThread, as the renderer and the display use).
#include <cuda_runtime_api.h>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "device/cuda_buffer.h"
#include "pipeline/jpeg_encoder.h"

namespace cinevol {
namespace {

void Check(nvjpegStatus_t status, const char* call) {
  if (status != NVJPEG_STATUS_SUCCESS) throw std::runtime_error(fmt::format("{} failed: nvJPEG status {}", call, int(status)));
}

nvjpegChromaSubsampling_t ToNvjpeg(ChromaSubsampling chroma) {
  switch (chroma) {
    case ChromaSubsampling::k444:
      return NVJPEG_CSS_444;
    case ChromaSubsampling::k422:
      return NVJPEG_CSS_422;
    case ChromaSubsampling::k420:
      return NVJPEG_CSS_420;
  }
  throw std::invalid_argument("unknown chroma subsampling");
}

// cudaStream_t and NvjpegStream are both CUstream_st*.
NvjpegStream Stream() { return cudaStreamPerThread; }

class NvjpegEncoder final : public DeviceJpegEncoder {
 public:
  explicit NvjpegEncoder(std::shared_ptr<const NvjpegLibrary> library) : lib_(std::move(library)) {
    try {
      Check(lib_->create_simple(&handle_), "nvjpegCreateSimple");
      Check(lib_->encoder_state_create(handle_, &state_, Stream()), "nvjpegEncoderStateCreate");
      Check(lib_->encoder_params_create(handle_, &params_, Stream()), "nvjpegEncoderParamsCreate");
    } catch (...) {
      Release();
      throw;
    }
  }
  ~NvjpegEncoder() override { Release(); }

  std::vector<std::uint8_t> Encode(const YccPlanes& planes, int quality) override {
    // The display's kernel first, so the time measured is the encode's alone.
    CINEVOL_CUDA_CHECK(cudaStreamSynchronize(Stream()));
    const auto start = std::chrono::steady_clock::now();
    SetParams(std::clamp(quality, 1, 100), planes.chroma);
    Check(lib_->encode_yuv(handle_, state_, params_, &Source(planes), ToNvjpeg(planes.chroma), planes.width,
                           planes.height, Stream()),
          "nvjpegEncodeYUV");
    std::size_t length = 0;
    Check(lib_->encode_retrieve_bitstream(handle_, state_, nullptr, &length, Stream()),
          "nvjpegEncodeRetrieveBitstream");
    std::vector<std::uint8_t> jpeg(length);
    Check(lib_->encode_retrieve_bitstream(handle_, state_, jpeg.data(), &length, Stream()),
          "nvjpegEncodeRetrieveBitstream");
    CINEVOL_CUDA_CHECK(cudaStreamSynchronize(Stream()));
    jpeg.resize(length);
    last_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return jpeg;
  }

  double LastMilliseconds() const override { return last_ms_; }

 private:
  // The planes as ImageYcc8 lays them out: tightly packed, one after another.
  nvjpegImage_t& Source(const YccPlanes& planes) {
    const std::size_t chroma_pitch = std::size_t(ChromaWidth(planes.width, planes.chroma));
    source_ = {};
    source_.channel[0] = planes.y;
    source_.channel[1] = planes.cb;
    source_.channel[2] = planes.cr;
    source_.pitch[0] = std::size_t(planes.width);
    source_.pitch[1] = source_.pitch[2] = chroma_pitch;
    return source_;
  }

  // Parameters change only with the session's settings (final frames take
  // their own quality), so they are set only when they differ.
  void SetParams(int quality, ChromaSubsampling chroma) {
    if (quality != quality_) {
      Check(lib_->encoder_params_set_quality(params_, quality, Stream()), "nvjpegEncoderParamsSetQuality");
      quality_ = quality;
    }
    if (!has_chroma_ || chroma != chroma_) {
      Check(lib_->encoder_params_set_sampling_factors(params_, ToNvjpeg(chroma), Stream()),
            "nvjpegEncoderParamsSetSamplingFactors");
      chroma_ = chroma;
      has_chroma_ = true;
    }
  }

  void Release() {
    if (params_) lib_->encoder_params_destroy(params_);
    if (state_) lib_->encoder_state_destroy(state_);
    if (handle_) lib_->destroy(handle_);
    params_ = nullptr, state_ = nullptr, handle_ = nullptr;
  }

  std::shared_ptr<const NvjpegLibrary> lib_;
  nvjpegHandle_t handle_ = nullptr;
  nvjpegEncoderState_t state_ = nullptr;
  nvjpegEncoderParams_t params_ = nullptr;
  nvjpegImage_t source_{};
  int quality_ = 0;  // 0: not set yet
  ChromaSubsampling chroma_ = ChromaSubsampling::k420;
  bool has_chroma_ = false;
  double last_ms_ = 0;
};

}  // namespace

std::unique_ptr<DeviceJpegEncoder> MakeNvjpegEncoder(std::shared_ptr<const NvjpegLibrary> library) {
  if (!library) throw std::invalid_argument("MakeNvjpegEncoder without the library");
  return std::make_unique<NvjpegEncoder>(std::move(library));
}

}  // namespace cinevol
