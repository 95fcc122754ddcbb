// Small analytic scenes for renderer tests: a uniform cube seen along an axis
// under a uniform environment, with knobs for what each test varies.
#pragma once

#include <memory>
#include <utility>
#include <vector>

#include "core/volume.h"
#include "io/phantom.h"
#include "render/renderer.h"

namespace cinevol::testing {

// A cube phantom of `size` voxels, every voxel `value`.
inline std::shared_ptr<const Volume> UniformCube(int size = 16, float spacing = 2.0f, float value = 1.0f) {
  v1::Phantom p;
  p.set_kind(v1::Phantom::CUBE);
  p.set_size(size);
  p.set_spacing(spacing);
  p.set_value(value);
  p.set_background(value);
  return std::make_shared<const Volume>(MakePhantom(p));
}

// Constant opacity 1 and albedo `albedo` at every value: sigma_t = density.
inline TransferFunction ConstantMedium(float density, float albedo, float gradient_factor = 0.0f) {
  TransferFunction tf;
  const Vec3f a{albedo, albedo, albedo};
  tf.points = {{-1e6f, 1.0f, a, {}, 0.5f, {}}, {1e6f, 1.0f, a, {}, 0.5f, {}}};
  tf.density_scale = density;
  tf.gradient_factor = gradient_factor;
  return tf;
}

inline LightSetup UniformSky(float radiance = 1.0f) {
  LightSetup s;
  s.environment.kind = Environment::Kind::kUniform;
  s.environment.zenith = {radiance, radiance, radiance};
  return s;
}

// A ball of radius 20 mm (value 1000) in a 64 mm cube of 0, and a transfer
// function that makes it an opaque surface (shaded by gradients) or, with
// `gradient_factor` 0, a medium shaded by the phase function alone.
inline std::shared_ptr<const Volume> Ball() {
  const int n = 32;
  std::vector<float> values(std::size_t(n) * n * n, 0.0f);
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x)
        values[(std::size_t(z) * n + y) * n + x] = Length(Vec3f{x - 15.5f, y - 15.5f, z - 15.5f}) <= 10.0f ? 1000 : 0;
  return std::make_shared<const Volume>(Vec3i{n, n, n}, Vec3f{2, 2, 2}, std::move(values), VolumeMetadata{});
}
inline TransferFunction BallSurface(float gradient_factor = 1.0f) {
  TransferFunction tf;
  tf.points = {{400, 0, {0.8f, 0.8f, 0.8f}, {}, 0.5f, {}}, {450, 1, {0.8f, 0.8f, 0.8f}, {}, 0.5f, {}}};
  tf.density_scale = 5;
  tf.gradient_factor = gradient_factor;
  return tf;
}

// Looking along +y at the volume from far away, so rays through the middle
// cross the cube along y.
inline Camera AxisCamera(int width = 16, int height = 16, float distance = 4000.0f, float fov_deg = 0.2f) {
  return LookAt({0, -distance, 0}, {0, 0, 0}, {0, 0, 1}, fov_deg, width, height);
}

}  // namespace cinevol::testing
