// The last device stage of a frame: blend the denoised image towards the
// plain accumulation as samples pile up, tone map to 8-bit sRGB, and copy the
// result to the host (3 bytes a pixel instead of 12). Runs on the backend
// that rendered the frame, from one source (denoise/backend_*.h).
#pragma once

#include <cstdint>
#include <memory>

#include "core/image.h"
#include "core/tone_map.h"
#include "core/vec.h"

namespace cinevol {

struct DisplayInputs {
  int width = 0, height = 0;
  const Vec3f* denoised = nullptr;         // backend memory
  const Vec3f* accumulated_sum = nullptr;  // backend memory: sum of frame means
  float inv_frames = 0;                    // 1 / frames in accumulated_sum
  float blend = 0;                         // 0: denoised only, 1: accumulation only
  float exposure = 0;                      // stops
};

struct DisplayPass {
  DisplayInputs in;
  std::uint8_t* rgb;
  float exposure_scale;

  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * in.width + x;
    Vec3f c = in.denoised[i];
    if (in.blend >= 1.0f) {
      c = in.accumulated_sum[i] * in.inv_frames;
    } else if (in.blend > 0.0f) {
      c = c * (1.0f - in.blend) + in.accumulated_sum[i] * (in.inv_frames * in.blend);
    }
    ToneMapPixel(c, exposure_scale, rgb + 3 * i);
  }
};

class Display {
 public:
  virtual ~Display() = default;
  virtual ImageRgb8 Run(const DisplayInputs& inputs) = 0;
};

// Runs DisplayPass over backend B's memory and downloads the bytes.
template <class B>
class DisplayOn final : public Display {
 public:
  ImageRgb8 Run(const DisplayInputs& in) override {
    rgb_.Resize(std::size_t(in.width) * in.height * 3);
    B::ForEachPixel(in.width, in.height, DisplayPass{in, rgb_.data(), exp2f(in.exposure)});
    return {in.width, in.height, rgb_.Download()};
  }

 private:
  typename B::template Buffer<std::uint8_t> rgb_;
};

std::unique_ptr<Display> MakeCpuDisplay();
#if CINEVOL_WITH_CUDA
std::unique_ptr<Display> MakeCudaDisplay();
#endif

}  // namespace cinevol
