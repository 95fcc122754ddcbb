// Building the renderer's host-side tables.
#include "render/scene_data.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>

namespace cinevol {

float MaxExtinction(Vec3f spacing_mm) { return kMaxOpticalDepthPerVoxel / MinComponent(spacing_mm); }

std::vector<float> ComputeMajorants(const BrickRanges& ranges, const float* sigma_t, int n, float entry_scale,
                                    float entry_offset) {
  // Sparse table: level k holds the max over 2^k consecutive entries, so any
  // range's max is two lookups.
  const int levels = std::bit_width(unsigned(n));
  std::vector<std::vector<float>> table(levels);
  table[0].assign(sigma_t, sigma_t + n);
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
    // Within the table; a bound that is not a number bounds nothing: the whole table.
    const int first = lo >= 0.0f ? int(std::min(lo, float(n - 1))) : 0;
    const int last = hi <= float(n - 1) ? int(std::max(hi, 0.0f)) : n - 1;
    majorants[i] = range_max(first, std::max(first, last));
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
  labels_ = nullptr;  // a segmentation belongs to its volume
  UpdateTables();
}

void SceneData::SetTransferFunction(const TransferFunction& tf) {
  tf_ = tf;
  UpdateTables();
}

namespace {

// Where `table` puts `volume`'s stored voxels: entry = stored * scale + offset.
void SetEntryMapping(const PreparedVolume& volume, const TransferTable& table, TransferView& view) {
  // In double: a narrow range (1e-37 wide) or a wide one (2e30) overflows
  // one factor in float where the product is an ordinary number.
  const double to_entry = double(TransferTable::kEntries - 1) / (double(table.value_max) - table.value_min);
  view.entry_scale = float(volume.value_scale() * to_entry);
  view.entry_offset = float((double(volume.value_offset()) - table.value_min) * to_entry);
}

}  // namespace

void SceneData::SetFusion(std::shared_ptr<const PreparedVolume> fused, const FusionSetup& setup) {
  fused_table_ = {};
  fused_ = setup.transfer_function.points.empty() ? nullptr : std::move(fused);
  if (fused_) {
    const Volume& v = fused_->volume();
    fused_to_volume_ = setup.to_volume;
    // Clamped as the scene volume's extinction is, at the finer spacing of the two.
    float max_sigma_t = MaxExtinction(v.spacing_mm());
    if (volume_) max_sigma_t = std::max(max_sigma_t, MaxExtinction(volume_->volume().spacing_mm()));
    fused_table_ = BuildTransferTable(setup.transfer_function, v.min_value(), v.max_value(), max_sigma_t);
  }
  UpdateFusedMajorants();
}

void SceneData::UpdateFusedMajorants() {
  fused_majorants_.clear();
  if (!fused_ || !volume_ || !majorants_ || majorants_->empty()) return;
  // The second volume's bound on each of its own bricks (their ranges hold
  // the voxels a lookup inside them reads), from its table.
  TransferView mapping;
  SetEntryMapping(*fused_, fused_table_, mapping);
  const BrickRanges& theirs = fused_->brick_ranges(Reconstruction::kTrilinear);
  const std::vector<float> their_bounds = ComputeMajorants(theirs, fused_table_.sigma_t.data(), TransferTable::kEntries,
                                                           mapping.entry_scale, mapping.entry_offset);
  const Volume& f = fused_->volume();
  const Vec3f their_min = f.extent_mm() * -0.5f, their_brick_mm = f.spacing_mm() * ToFloat(fused_->brick_size());
  // Each of our bricks: its box mapped into their frame, the bricks of theirs it meets, the largest bound of those.
  const Volume& v = volume_->volume();
  const Vec3i ours = volume_->brick_ranges(reconstruction_).bricks;
  const Vec3f our_min = v.extent_mm() * -0.5f, our_brick_mm = v.spacing_mm() * ToFloat(volume_->brick_size());
  fused_majorants_ = *majorants_;
  for (int z = 0; z < ours.z; ++z) {
    for (int y = 0; y < ours.y; ++y) {
      for (int x = 0; x < ours.x; ++x) {
        Vec3f lo{3.4e38f, 3.4e38f, 3.4e38f}, hi = -lo;
        for (int corner = 0; corner < 8; ++corner) {
          const Vec3f at = our_min + our_brick_mm * Vec3f{float(x + (corner & 1)), float(y + (corner >> 1 & 1)),
                                                          float(z + (corner >> 2 & 1))};
          const Vec3f q = (fused_to_volume_(at) - their_min) / their_brick_mm;
          lo = Min(lo, q);
          hi = Max(hi, q);
        }
        const Vec3i from{std::max(0, int(std::floor(lo.x))), std::max(0, int(std::floor(lo.y))),
                         std::max(0, int(std::floor(lo.z)))};
        const Vec3i to{std::min(theirs.bricks.x - 1, int(std::floor(hi.x))),
                       std::min(theirs.bricks.y - 1, int(std::floor(hi.y))),
                       std::min(theirs.bricks.z - 1, int(std::floor(hi.z)))};
        float bound = 0.0f;
        for (int k = from.z; k <= to.z; ++k) {
          for (int j = from.y; j <= to.y; ++j) {
            for (int i = from.x; i <= to.x; ++i) {
              bound = std::max(bound, their_bounds[(std::size_t(k) * theirs.bricks.y + j) * theirs.bricks.x + i]);
            }
          }
        }
        fused_majorants_[(std::size_t(z) * ours.y + y) * ours.x + x] += bound;
      }
    }
  }
}

void SceneData::SetReconstruction(Reconstruction r) {
  if (r == reconstruction_) return;
  reconstruction_ = r;
  if (volume_ && !tf_.points.empty()) UpdateMajorants();
}

void SceneData::SetLabels(std::shared_ptr<const LabelCopy> labels, const LabelSetup& setup) {
  if (labels && (!volume_ || labels->labels().dims != volume_->volume().dims() ||
                 labels->brick_labels().offsets.size() != volume_->brick_ranges(reconstruction_).min.size() + 1)) {
    throw std::invalid_argument("SceneData::SetLabels: the labels are not on the volume's grid and bricks");
  }
  labels_ = std::move(labels);
  label_setup_ = setup;
  label_materials_.clear();
  if (labels_) {
    // By stored value: labels, then the shells and the table (core/labels.h).
    const LabelVolume& volume = labels_->labels();
    label_materials_.resize(std::size_t(volume.value_count()));
    for (int value = 0; value < volume.value_count(); ++value) {
      const LabelStyle& style = label_setup_.StyleOfValue(volume, value);
      LabelMaterial& m = label_materials_[value];
      m.opacity_scale = style.visible ? style.opacity_scale : 0.0f;
      m.has_color = style.has_color;
      m.color = style.color;
      m.table = style.transfer + 1;
    }
  }
  UpdateTables();
}

// Appends `more`'s entries to `table`'s (labels' own tables after the image's).
static void AppendTable(TransferTable& table, const TransferTable& more) {
  auto append = [](auto& to, const auto& from) { to.insert(to.end(), from.begin(), from.end()); };
  append(table.sigma_t, more.sigma_t);
  append(table.diffuse_opacity, more.diffuse_opacity);
  append(table.specular_roughness, more.specular_roughness);
  append(table.emission, more.emission);
  table.has_emission |= more.has_emission;
}

void SceneData::UpdateTables() {
  if (!volume_ || tf_.points.empty()) return;
  const float lo = volume_->volume().min_value(), hi = volume_->volume().max_value();
  const float max_sigma_t = MaxExtinction(volume_->volume().spacing_mm());
  table_ = BuildTransferTable(tf_, lo, hi, max_sigma_t);
  if (labels_) {
    for (const TransferFunction& own : label_setup_.transfer_functions) {
      AppendTable(table_, BuildTransferTable(own, lo, hi, max_sigma_t));
    }
  }
  UpdateMajorants();
}

void SceneData::UpdateMajorants() {
  MajorantKey key{volume_.get(), reconstruction_, labels_.get(), table_.sigma_t, {}};
  if (labels_) {
    for (const LabelMaterial& m : label_materials_) {
      key.label_scales.push_back(m.opacity_scale);
      key.label_scales.push_back(float(m.table));
    }
  }
  majorants_ = VolumeCache::Get().AcquireMajorants(key, [this] { return BuildMajorants(); });
  ++majorant_builds_;
  UpdateFusedMajorants();
}

std::vector<float> SceneData::BuildMajorants() const {
  const RenderScene view = HostView();
  const BrickRanges& ranges = volume_->brick_ranges(reconstruction_);
  const std::size_t n = TransferTable::kEntries;
  auto majorants_of_table = [&](int k) {
    return ComputeMajorants(ranges, table_.sigma_t.data() + k * n, int(n), view.transfer.entry_scale,
                            view.transfer.entry_offset);
  };
  std::vector<float> majorants = majorants_of_table(0);
  if (labels_) {
    // A brick's bound is the largest over the labels it holds, each label's
    // table bound scaled by its opacity scale (0 for hidden labels).
    std::vector<std::vector<float>> by_table{majorants};
    for (std::size_t k = 1; k * n < table_.sigma_t.size(); ++k) by_table.push_back(majorants_of_table(int(k)));
    for (std::size_t b = 0; b < majorants.size(); ++b) {
      float bound = 0.0f;
      const BrickLabels& present = labels_->brick_labels();
      for (std::uint32_t i = present.offsets[b]; i < present.offsets[b + 1]; ++i) {
        const LabelMaterial& m = label_materials_[present.labels[i]];
        bound = std::max(bound, m.opacity_scale * by_table[m.table][b]);
      }
      majorants[b] = std::min(bound, view.transfer.max_sigma_t);  // as the integrator clamps scaled extinction
    }
  }
  return majorants;
}

void SceneData::SetLights(const LightSetup& setup) {
  lights_ = setup;
  // Kernels turn directions into map texels relative to the rotation: taken
  // within one turn, any finite rotation keeps its precision.
  const float rotation = std::remainder(lights_.environment.rotation, 2.0f * kPi);
  lights_.environment.rotation = std::isfinite(rotation) ? rotation : 0.0f;
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
    const float value_scale = volume_->value_scale();
    s.volume.voxels = volume_->voxels();
    s.volume.dims = v.dims();
    s.volume.spacing = v.spacing_mm();
    s.volume.inv_spacing = Vec3f{1, 1, 1} / v.spacing_mm();
    s.volume.box_max = v.extent_mm() * 0.5f;
    s.volume.box_min = -s.volume.box_max;
    s.volume.tricubic = reconstruction_ == Reconstruction::kTricubic;

    SetEntryMapping(*volume_, table_, s.transfer);
    const double range = double(v.max_value()) - v.min_value();
    s.transfer.gradient_normaliser =
        range > 0 ? float(value_scale * double(MinComponent(v.spacing_mm())) / range) : 0.0f;
    s.transfer.max_sigma_t = MaxExtinction(v.spacing_mm());

    s.majorants.majorant = majorants_ ? majorants_->data() : nullptr;
    s.majorants.bricks = volume_->brick_ranges(reconstruction_).bricks;
    s.majorants.box_min = s.volume.box_min;
    s.majorants.inv_brick_size = Vec3f{1, 1, 1} / (v.spacing_mm() * ToFloat(volume_->brick_size()));
  }
  if (labels_) s.labels = {labels_->labels().labels.data(), label_materials_.data()};
  if (fused_) {
    const Volume& f = fused_->volume();
    s.fused.volume.voxels = fused_->voxels();
    s.fused.volume.dims = f.dims();
    s.fused.volume.spacing = f.spacing_mm();
    s.fused.volume.inv_spacing = Vec3f{1, 1, 1} / f.spacing_mm();
    s.fused.volume.box_max = f.extent_mm() * 0.5f;
    s.fused.volume.box_min = -s.fused.volume.box_max;
    s.fused.to_volume = fused_to_volume_;
    SetEntryMapping(*fused_, fused_table_, s.fused.transfer);
    s.fused.transfer.sigma_t = fused_table_.sigma_t.data();
    s.fused.transfer.diffuse_opacity = fused_table_.diffuse_opacity.data();
    s.fused.transfer.specular_roughness = fused_table_.specular_roughness.data();
    s.fused.transfer.emission = fused_table_.emission.data();
    s.fused.transfer.phase_g = fused_table_.phase_g;
    if (!fused_majorants_.empty()) s.majorants.majorant = fused_majorants_.data();
  }
  s.transfer.sigma_t = table_.sigma_t.data();
  s.transfer.diffuse_opacity = table_.diffuse_opacity.data();
  s.transfer.specular_roughness = table_.specular_roughness.data();
  s.transfer.emission = table_.emission.data();
  s.transfer.gradient_factor = table_.gradient_factor;
  s.transfer.phase_g = table_.phase_g;
  s.has_emission = table_.has_emission || (fused_ && fused_table_.has_emission);

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
    s.environment.map = {environment_.texels.data(),
                         environment_.marginal_cdf.data(),
                         environment_.conditional_cdf.data(),
                         environment_.weight.data(),
                         environment_.weight_integral,
                         env.map.width,
                         env.map.height};
  }
  s.has_hittable_lights = s.environment.kind != Environment::Kind::kNone;
  for (const Light& l : lights_.lights) s.has_hittable_lights |= l.kind == LightKind::kArea;
  return s;
}

}  // namespace cinevol
