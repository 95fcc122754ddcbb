// Interactive resolution: a frame rendered at a fraction of the viewport
// while the view moves is stretched back to the viewport on the backend that
// rendered it, in linear radiance before tone mapping, with bilinear
// filtering between pixel centres (edges clamp).
#pragma once

#include <memory>

#include "core/sampling.h"
#include "core/vec.h"

namespace cinevol {

struct UpsamplePass {
  const Vec3f* source;
  int source_width, source_height;
  Vec3f* target;     // operator() writes here; Sample alone does not need it
  int target_width;
  float scale_x, scale_y;  // source pixels per target pixel

  // Target pixel (x, y)'s radiance.
  CINEVOL_HD Vec3f Sample(int x, int y) const {
    const float sx = Clamp((float(x) + 0.5f) * scale_x - 0.5f, 0.0f, float(source_width - 1));
    const float sy = Clamp((float(y) + 0.5f) * scale_y - 0.5f, 0.0f, float(source_height - 1));
    const int x0 = int(sx), y0 = int(sy);
    const int x1 = x0 + 1 < source_width ? x0 + 1 : x0, y1 = y0 + 1 < source_height ? y0 + 1 : y0;
    const float fx = sx - float(x0), fy = sy - float(y0);
    const Vec3f top = source[y0 * source_width + x0] * (1.0f - fx) + source[y0 * source_width + x1] * fx;
    const Vec3f bottom = source[y1 * source_width + x0] * (1.0f - fx) + source[y1 * source_width + x1] * fx;
    return top * (1.0f - fy) + bottom * fy;
  }

  CINEVOL_HD void operator()(int x, int y) const { target[y * target_width + x] = Sample(x, y); }
};

class Upsampler {
 public:
  virtual ~Upsampler() = default;
  // `source` (width x height, backend memory) stretched to target_width x
  // target_height; the result stays valid until the next call.
  virtual const Vec3f* Run(const Vec3f* source, int width, int height, int target_width, int target_height) = 0;
};

template <class B>
class UpsamplerOn final : public Upsampler {
 public:
  const Vec3f* Run(const Vec3f* source, int width, int height, int target_width, int target_height) override {
    target_.Resize(std::size_t(target_width) * target_height);
    const UpsamplePass pass{source, width, height, target_.data(), target_width,
                            float(width) / float(target_width), float(height) / float(target_height)};
    B::ForEachPixel(target_width, target_height, pass);
    return target_.data();
  }

 private:
  typename B::template Buffer<Vec3f> target_;
};

std::unique_ptr<Upsampler> MakeCpuUpsampler();
#if CINEVOL_WITH_CUDA
std::unique_ptr<Upsampler> MakeCudaUpsampler();
#endif

}  // namespace cinevol
