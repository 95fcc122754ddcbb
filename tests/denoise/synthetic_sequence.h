// A synthetic frame sequence with a known answer: a textured plane seen by a
// movable camera, each pixel's noisy value its true radiance times Gamma(2)/2
// noise (mean 1), as a 2 spp render would give.
#pragma once

#include <cmath>
#include <utility>
#include <vector>

#include "core/camera.h"
#include "core/rng.h"
#include "denoise/denoiser.h"

namespace cinevol::testing {

class SyntheticSequence {
 public:
  SyntheticSequence(int width, int height) : width_(width), height_(height) {
    camera_ = LookAt({0, -300, 0}, {0, 0, 0}, {0, 0, 1}, 30, width, height);
  }

  // Radiance of the plane y = 0 at (x, z): smooth shading plus a sharp edge.
  static Vec3f Texture(float x, float z) {
    const float shade = 1.0f + 0.5f * std::sin(x * 0.08f) * std::sin(z * 0.05f);
    const float edge = x > 10.0f ? 1.0f : 0.3f;
    return Vec3f{0.9f, 0.6f, 0.4f} * (shade * edge);
  }

  void MoveCamera(Vec3f offset) {
    moved_ = true;
    camera_ = LookAt(camera_.eye + offset, camera_.eye + offset + camera_.forward * 300.0f, {0, 0, 1}, 30, width_,
                     height_);
  }

  // Fills the next frame: truth, noisy radiance, first hits, albedo.
  DenoiseFrame Next(float exposure = 1.0f) {
    const std::size_t n = std::size_t(width_) * height_;
    truth_.assign(n, {});
    radiance_.assign(n, {});
    first_hit_.assign(n, {});
    albedo_.assign(n, Vec3f{0.9f, 0.6f, 0.4f});
    Pcg32 rng(1234, frame_++);
    for (int y = 0; y < height_; ++y) {
      for (int x = 0; x < width_; ++x) {
        const Ray r = camera_.GenerateRay(x + 0.5f, y + 0.5f, 0.5f, 0.5f);
        const float t = -r.origin.y / r.direction.y;
        const Vec3f hit = r.origin + r.direction * t;
        const std::size_t i = std::size_t(y) * width_ + x;
        truth_[i] = Texture(hit.x, hit.z) * exposure;
        const float noise = -0.5f * (std::log(1.0f - rng.Uniform()) + std::log(1.0f - rng.Uniform()));
        radiance_[i] = truth_[i] * noise;
        first_hit_[i] = ToVec4(hit, 1.0f);
      }
    }
    DenoiseFrame f;
    f.width = width_;
    f.height = height_;
    f.radiance = radiance_.data();
    f.first_hit = first_hit_.data();
    f.albedo = albedo_.data();
    f.camera = camera_;
    f.changed = frame_ == 1 || std::exchange(moved_, false);  // the first frame, and after a move
    return f;
  }

  std::vector<Vec3f>& radiance() { return radiance_; }
  const std::vector<Vec3f>& truth() const { return truth_; }
  ImageRgbF TruthImage() const { return {width_, height_, truth_}; }
  ImageRgbF NoisyImage() const { return {width_, height_, radiance_}; }

 private:
  int width_, height_;
  Camera camera_;
  std::uint64_t frame_ = 0;
  bool moved_ = false;
  std::vector<Vec3f> truth_, radiance_, albedo_;
  std::vector<Vec4f> first_hit_;
};

}  // namespace cinevol::testing
