// Building the renderer's host-side tables.
#include "render/scene_data.h"

#include <algorithm>
#include <bit>
#include <cmath>

namespace cinevol {

std::vector<float> ComputeMajorants(const BrickRanges& ranges, const std::vector<float>& sigma_t,
                                    float entry_scale, float entry_offset) {
  // Sparse table: level k holds the max over 2^k consecutive entries, so any
  // range's max is two lookups.
  const int n = static_cast<int>(sigma_t.size());
  const int levels = std::bit_width(unsigned(n));
  std::vector<std::vector<float>> table(levels);
  table[0] = sigma_t;
  for (int k = 1; k < levels; ++k) {
    const int span = 1 << k;
    table[k].resize(n - span + 1);
    for (int i = 0; i + span <= n; ++i) {
      table[k][i] = std::max(table[k - 1][i], table[k - 1][i + span / 2]);
    }
  }
  auto range_max = [&](int lo, int hi) {
    const int k = std::bit_width(unsigned(hi - lo + 1)) - 1;
    return std::max(table[k][lo], table[k][hi - (1 << k) + 1]);
  };
  std::vector<float> majorants(ranges.min.size());
  for (std::size_t i = 0; i < majorants.size(); ++i) {
    // One entry of slack each side absorbs rounding differences between this
    // bound and the renderer's entry arithmetic (an FMA on the GPU).
    const float lo = std::floor(ranges.min[i] * entry_scale + entry_offset) - 1.0f;
    const float hi = std::ceil(ranges.max[i] * entry_scale + entry_offset) + 1.0f;
    majorants[i] = range_max(int(std::clamp(lo, 0.0f, float(n - 1))), int(std::clamp(hi, 0.0f, float(n - 1))));
  }
  return majorants;
}

EnvironmentDistribution BuildEnvironmentDistribution(const ImageRgbF& map) {
  EnvironmentDistribution d;
  const int w = map.width, h = map.height;
  d.texels.resize(map.pixels.size());
  d.weight.resize(map.pixels.size());
  d.marginal_cdf.assign(h + 1, 0.0f);
  d.conditional_cdf.assign(std::size_t(h) * (w + 1), 0.0f);
  double total = 0;
  for (int y = 0; y < h; ++y) {
    const float sin_theta = std::sin((float(y) + 0.5f) / float(h) * kPi);
    float* cdf = &d.conditional_cdf[std::size_t(y) * (w + 1)];
    double row = 0;
    for (int x = 0; x < w; ++x) {
      const std::size_t i = std::size_t(y) * w + x;
      const Vec3f c = map.pixels[i];
      d.texels[i] = ToVec4(c, 0.0f);
      d.weight[i] = IsFinite(c) ? std::max(0.0f, Luminance(c)) * sin_theta : 0.0f;
      row += d.weight[i];
      cdf[x + 1] = float(row);
    }
    for (int x = 1; x <= w; ++x) cdf[x] = row > 0 ? float(cdf[x] / row) : float(x) / float(w);
    total += row;
    d.marginal_cdf[y + 1] = float(total);
  }
  for (int y = 1; y <= h; ++y) d.marginal_cdf[y] = total > 0 ? float(d.marginal_cdf[y] / total) : float(y) / float(h);
  d.weight_integral = float(total / (double(w) * h));
  return d;
}

void SceneData::SetVolume(std::shared_ptr<const PreparedVolume> volume) {
  volume_ = std::move(volume);
  if (!tf_.points.empty()) SetTransferFunction(tf_);
}

void SceneData::SetTransferFunction(const TransferFunction& tf) {
  tf_ = tf;
  if (!volume_) return;
  table_ = BuildTransferTable(tf_, volume_->volume().min_value(), volume_->volume().max_value());
  UpdateMajorants();
}

void SceneData::UpdateMajorants() {
  const RenderScene view = HostView();
  majorants_ =
      ComputeMajorants(volume_->brick_ranges(), table_.sigma_t, view.transfer.entry_scale, view.transfer.entry_offset);
  ++majorant_builds_;
}

void SceneData::SetLights(const LightSetup& setup) {
  lights_ = setup;
  environment_ = {};
  if (setup.environment.kind == Environment::Kind::kMap) {
    environment_ = BuildEnvironmentDistribution(setup.environment.map);
    if (!(environment_.weight_integral > 0.0f)) lights_.environment.kind = Environment::Kind::kNone;
  }
}

RenderScene SceneData::HostView() const {
  RenderScene s;
  s.clip = clip_;
  if (volume_) {
    const Volume& v = volume_->volume();
    const float value_scale = volume_->value_scale(), value_offset = volume_->value_offset();
    s.volume.voxels = volume_->voxels();
    s.volume.dims = v.dims();
    s.volume.spacing = v.spacing_mm();
    s.volume.inv_spacing = Vec3f{1, 1, 1} / v.spacing_mm();
    s.volume.box_max = v.extent_mm() * 0.5f;
    s.volume.box_min = -s.volume.box_max;

    const float n1 = float(TransferTable::kEntries - 1);
    const float to_entry = n1 / (table_.value_max - table_.value_min);
    s.transfer.entry_scale = value_scale * to_entry;
    s.transfer.entry_offset = (value_offset - table_.value_min) * to_entry;
    const float range = v.max_value() - v.min_value();
    s.transfer.gradient_normaliser = range > 0 ? value_scale * MinComponent(v.spacing_mm()) / range : 0.0f;

    s.majorants.majorant = majorants_.data();
    s.majorants.bricks = volume_->brick_ranges().bricks;
    s.majorants.box_min = s.volume.box_min;
    s.majorants.inv_brick_size = Vec3f{1, 1, 1} / (v.spacing_mm() * ToFloat(volume_->brick_size()));
  }
  s.transfer.sigma_t = table_.sigma_t.data();
  s.transfer.diffuse_opacity = table_.diffuse_opacity.data();
  s.transfer.specular_roughness = table_.specular_roughness.data();
  s.transfer.emission = table_.emission.data();
  s.transfer.gradient_factor = table_.gradient_factor;
  s.transfer.phase_g = table_.phase_g;
  s.has_emission = table_.has_emission;

  s.lights = lights_.lights.data();
  s.light_count = static_cast<int>(lights_.lights.size());
  const EnvironmentSetup& env = lights_.environment;
  s.environment.kind = env.kind;
  s.environment.zenith = env.zenith;
  s.environment.horizon = env.horizon;
  s.environment.ground = env.ground;
  s.environment.up = env.up;
  s.environment.rotation = env.rotation;
  s.environment.visible = env.visible;
  if (env.kind == Environment::Kind::kMap) {
    s.environment.map = {environment_.texels.data(), environment_.marginal_cdf.data(),
                         environment_.conditional_cdf.data(), environment_.weight.data(),
                         environment_.weight_integral, env.map.width, env.map.height};
  }
  s.has_hittable_lights = s.environment.kind != Environment::Kind::kNone;
  for (const Light& l : lights_.lights) s.has_hittable_lights |= l.kind == LightKind::kArea;
  return s;
}

}  // namespace cinevol
