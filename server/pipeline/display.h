// The last device stage of a frame: tone map the frame's radiance (denoised,
// or refined: pipeline/refine.h) to 8-bit sRGB, convert to
// JPEG's YCbCr with the session's chroma subsampling, and copy the planes to
// the host (1.5 bytes a pixel at 4:2:0, instead of 12 of radiance), where the
// JPEG encoder takes them as they are; or, with a device JPEG encoder
// (pipeline/jpeg_encoder.h), encode them where they lie and copy only the
// JPEG. Runs on the backend that rendered the frame, from one source
// (device/cpu_backend.h, cuda_backend.cuh).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/image.h"
#include "core/tone_map.h"
#include "core/vec.h"
#include "core/ycc.h"
#include "pipeline/jpeg_encoder.h"
#include "pipeline/upsample.h"

namespace cinevol {

struct DisplayInputs {
  int width = 0, height = 0;
  const Vec3f* radiance = nullptr;  // backend memory: linear, what the frame shows
  float exposure = 0;               // stops
  ChromaSubsampling chroma = ChromaSubsampling::k420;
  // Each plane sample keeps the code the display showed last frame while
  // its value is within a code of it (core/ycc.h HeldCode,
  // FrameSettings::hold_codes); false: plain rounding (a final frame).
  bool hold_codes = false;
};

// The tone map of core/tone_map.h, evaluated (GPUs; the CPU uses the same
// codes from a table: pipeline/tone_map_table.h).
struct FormulaToneMap {
  CINEVOL_HD void operator()(Vec3f c, float exposure_scale, std::uint8_t* rgb, float* position) const {
    ToneMapPixel(c, exposure_scale, rgb, position);
  }
};

// The radiance a pixel shows: the frame's own, or (a moving frame on the
// CPU) upsampled from a smaller frame on the way, with the upsampler's
// arithmetic and without a viewport-sized buffer in between.
struct FrameRadiance {
  const Vec3f* radiance;
  int width;
  CINEVOL_HD Vec3f operator()(int x, int y) const { return radiance[y * width + x]; }
};
struct UpsampledRadiance {
  UpsamplePass pass;
  CINEVOL_HD Vec3f operator()(int x, int y) const { return pass.Sample(x, y); }
};

// A pixel's displayed 8-bit sRGB.
template <class Radiance = FrameRadiance, class ToneMap = FormulaToneMap>
struct DisplayedPixel {
  Radiance radiance;
  ToneMap tone_map;
  float exposure_scale;

  // `position`, where not null: the values before rounding (DisplayPosition).
  CINEVOL_HD void operator()(int x, int y, std::uint8_t* rgb, float* position = nullptr) const {
    tone_map(radiance(x, y), exposure_scale, rgb, position);
  }
};

// Runs over the chroma planes: each call converts the pixel block behind one
// chroma sample (one pixel at 4:4:4).
// `hold`: `out` holds the previous frame's planes, kept where they are
// within a code (DisplayInputs::hold_codes).
template <class Pixel>
struct DisplayPass {
  Pixel pixel;
  YccPlanes out;
  bool hold;

  CINEVOL_HD void operator()(int cx, int cy) const { WriteYccBlock(out, cx, cy, pixel, hold); }
};

// The displayed pixels themselves, interleaved RGB: a lossless final frame.
template <class Pixel>
struct DisplayRgbPass {
  Pixel pixel;
  std::uint8_t* out;
  int width;

  CINEVOL_HD void operator()(int x, int y) const { pixel(x, y, out + 3 * (std::size_t(y) * width + x)); }
};

class Display {
 public:
  virtual ~Display() = default;
  // The planes stay valid while the returned image (or a copy) lives, also
  // after later runs and after the Display is gone.
  virtual ImageYcc8 Run(const DisplayInputs& inputs) = 0;
  // The same for `source` (width x height, backend memory) upsampled to the
  // inputs' size as Upsampler::Run does; inputs.radiance is not read.
  virtual ImageYcc8 RunUpsampled(const DisplayInputs& inputs, const Vec3f* source, int width, int height) = 0;
  // The planes Run makes, encoded by `encoder` on the backend's device at
  // `quality`: only the JPEG leaves it. Its bytes are empty where the
  // encoder gave the frame back: LastPlanes() then has them for the host.
  virtual EncodedJpeg RunJpeg(const DisplayInputs& inputs, DeviceJpegEncoder& encoder, int quality) = 0;
  // The last Run's or RunJpeg's planes, copied to the host as Run returns them.
  virtual ImageYcc8 LastPlanes() = 0;
  // The same pixels as 8-bit sRGB (inputs.chroma does not apply), for a
  // frame that goes out losslessly: once per refinement, so not pipelined.
  virtual ImageRgb8 RunRgb(const DisplayInputs& inputs) = 0;
};

// The host buffers behind the frames a display returns. A frame shares its
// buffer; a buffer is written again only once no frame holds it, so a frame
// can be encoded on another thread while the next one renders. kKept
// buffers suffice for a session (it holds at most two frames: one encoding
// while the next renders); a caller holding more frames gets fresh buffers.
template <class HostBuffer>
class FrameBufferRing {
 public:
  static constexpr std::size_t kKept = 3;

  std::shared_ptr<HostBuffer> Next(std::size_t count) {
    for (const std::shared_ptr<HostBuffer>& buffer : buffers_) {
      if (buffer.use_count() == 1) {
        // Pairs with the release in the last frame's shared_ptr destructor:
        // that thread's reads come before this buffer's next write.
        std::atomic_thread_fence(std::memory_order_acquire);
        buffer->Resize(count);
        return buffer;
      }
    }
    auto fresh = std::make_shared<HostBuffer>();
    fresh->Resize(count);
    if (buffers_.size() < kKept) {
      buffers_.push_back(fresh);
    } else {
      buffers_[next_replaced_++ % kKept] = fresh;  // its frame keeps the old one alive
    }
    return fresh;
  }

 private:
  std::vector<std::shared_ptr<HostBuffer>> buffers_;
  std::size_t next_replaced_ = 0;
};

// Runs DisplayPass over backend B's memory and copies the planes into one of
// the ring's host buffers, waiting for the copy: the frame returned is ready
// to encode on any thread. (Waiting costs little: the stream has nothing else
// of this session's queued, and the next frame starts from this thread.)
// ToneMap: FormulaToneMap, or on the CPU the table's same codes.
template <class B, class ToneMap = FormulaToneMap>
class DisplayOn final : public Display {
 public:
  explicit DisplayOn(ToneMap tone_map = {}) : tone_map_(tone_map) {}

  ImageYcc8 Run(const DisplayInputs& in) override {
    return Planes(in, Pixel<FrameRadiance>(in, {in.radiance, in.width}));
  }

  ImageYcc8 RunUpsampled(const DisplayInputs& in, const Vec3f* source, int width, int height) override {
    const UpsamplePass up{source, width, height, nullptr, in.width, float(width) / float(in.width),
                          float(height) / float(in.height)};
    return Planes(in, Pixel<UpsampledRadiance>(in, {up}));
  }

  EncodedJpeg RunJpeg(const DisplayInputs& in, DeviceJpegEncoder& encoder, int quality) override {
    const YccPlanes planes = WritePlanes(in, Pixel<FrameRadiance>(in, {in.radiance, in.width}));
    return {in.width, in.height, encoder.Encode(planes, quality)};
  }

  ImageYcc8 LastPlanes() override {
    const PlanesLayout& layout = planes_layout_;
    const std::size_t bytes = planes_.size();
    const std::shared_ptr<HostBuffer> host = ring_.Next(bytes);
    planes_.Download(host->data());
    return {layout.width, layout.height, layout.chroma, std::shared_ptr<const std::uint8_t>(host, host->data()), bytes};
  }

  ImageRgb8 RunRgb(const DisplayInputs& in) override {
    ImageRgb8 image{in.width, in.height, std::vector<std::uint8_t>(std::size_t(in.width) * in.height * 3)};
    planes_.Resize(image.bytes.size());
    planes_layout_ = {};
    using P = DisplayedPixel<FrameRadiance, ToneMap>;
    B::ForEachPixel(in.width, in.height, DisplayRgbPass<P>{Pixel<FrameRadiance>(in, {in.radiance, in.width}),
                                                           planes_.data(), in.width});
    planes_.Download(image.bytes.data());
    return image;
  }

 private:
  template <class Radiance>
  DisplayedPixel<Radiance, ToneMap> Pixel(const DisplayInputs& in, Radiance radiance) const {
    return {radiance, tone_map_, exp2f(in.exposure)};
  }

  // The planes in backend memory (planes_), written.
  template <class P>
  YccPlanes WritePlanes(const DisplayInputs& in, const P& pixel) {
    const PlanesLayout& last = planes_layout_;
    const bool hold = in.hold_codes && last.width == in.width && last.height == in.height && last.chroma == in.chroma;
    planes_.Resize(YccBytes(in.width, in.height, in.chroma));
    planes_layout_ = {in.width, in.height, in.chroma};
    const YccPlanes out = YccPlanes::Of(planes_.data(), in.width, in.height, in.chroma);
    B::ForEachPixel(ChromaWidth(in.width, in.chroma), ChromaHeight(in.height, in.chroma),
                    DisplayPass<P>{pixel, out, hold});
    return out;
  }

  template <class P>
  ImageYcc8 Planes(const DisplayInputs& in, const P& pixel) {
    WritePlanes(in, pixel);
    return LastPlanes();
  }


  ToneMap tone_map_;
  using HostBuffer = typename B::template HostBuffer<std::uint8_t>;
  // The last frame's planes (or RunRgb's pixels), written in place: a frame
  // of the same layout holds their codes.
  typename B::template Buffer<std::uint8_t> planes_;
  struct PlanesLayout {
    int width = 0, height = 0;  // 0: planes_ holds no planes
    ChromaSubsampling chroma = ChromaSubsampling::k420;
  };
  PlanesLayout planes_layout_;
  FrameBufferRing<HostBuffer> ring_;
};

std::unique_ptr<Display> MakeCpuDisplay();
// What a viewer sees of host radiance: the CPU display pass at 4:4:4, back
// to RGB (tests and benches compare frames with references through it).
ImageRgb8 ShownOnCpu(const ImageRgbF& radiance, float exposure);
#if CINEVOL_WITH_CUDA
std::unique_ptr<Display> MakeCudaDisplay();
#endif

}  // namespace cinevol
