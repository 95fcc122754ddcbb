// Host-side tables of one renderer (CPU or CUDA): the transfer tables (the
// image's, then the labels' own) and the majorants they imply over the shared
// prepared volume's bricks (shared too, by renderers that classify alike), the
// labels' materials, lights and the environment map's sampling tables.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "core/label_view.h"
#include "core/labels.h"
#include "core/lights.h"
#include "core/transfer_function.h"
#include "render/prepared_volume.h"
#include "render/render_scene.h"

namespace cinevol {

// Extinction is clamped at this optical depth per voxel (the smallest
// spacing): kMaxOpticalDepthPerVoxel / min(spacing) per mm. A voxel at the
// clamp lets through e^-32 (1e-14) of the light, as opaque as anything
// denser looks; but delta tracking costs one lookup per 1/sigma mm of
// majorant, so above it the cost would grow with the density scale and
// nothing in the image with it (density scale 1e6 made a frame of the head
// phantom hundreds of times slower, and black: its paths ran out of budget).
inline constexpr float kMaxOpticalDepthPerVoxel = 32.0f;

// The extinction clamp of a volume with this spacing, per mm.
float MaxExtinction(Vec3f spacing_mm);

// Per-brick majorant: the largest extinction the table gives over the brick's
// value range (entries = stored * entry_scale + entry_offset).
// `sigma_t`: one table's `n` extinctions.
std::vector<float> ComputeMajorants(const BrickRanges& ranges, const float* sigma_t, int n, float entry_scale,
                                    float entry_offset);

// Sampling tables of an environment map (pbrt's Distribution2D).
struct EnvironmentDistribution {
  std::vector<Vec4f> texels;
  std::vector<float> weight, marginal_cdf, conditional_cdf;
  float weight_integral = 0;
};

EnvironmentDistribution BuildEnvironmentDistribution(const ImageRgbF& map);

class SceneData {
 public:
  // The prepared volume, shared with every renderer of it (VolumeCache).
  void SetVolume(std::shared_ptr<const PreparedVolume> volume);
  void SetTransferFunction(const TransferFunction& tf);
  void SetLights(const LightSetup& setup);
  void SetClipRegion(const ClipRegion& clip) { clip_ = clip; }
  void SetReconstruction(Reconstruction r);
  // A segmentation of the volume (VolumeCache::AcquireLabels, with the
  // volume's brick size) and how its labels show; null: none.
  void SetLabels(std::shared_ptr<const LabelCopy> labels, const LabelSetup& setup);
  // A second volume (VolumeCache's copy of it) and how it shows; null, or a
  // setup whose transfer function has no points: none in 3D.
  void SetFusion(std::shared_ptr<const PreparedVolume> fused, const FusionSetup& setup);

  bool has_volume() const { return volume_ != nullptr; }
  const PreparedVolume& volume() const { return *volume_; }
  // The majorants, shared with every renderer of the volume with the same
  // classification (VolumeCache::AcquireMajorants).
  const std::shared_ptr<const std::vector<float>>& shared_majorants() const { return majorants_; }
  const std::vector<float>& majorants() const {
    static const std::vector<float> kNone;
    return majorants_ ? *majorants_ : kNone;
  }
  // With a second volume in 3D, each brick's majorant plus the largest
  // extinction the second volume takes over the brick's region: this
  // renderer's own (the fusion is the session's); empty without one.
  const std::vector<float>& fused_majorants() const { return fused_majorants_; }
  // How many times the majorants were derived anew (volume and
  // transfer-function changes; built, or found shared): tests check that a
  // camera move derives none.
  std::uint64_t majorant_builds() const { return majorant_builds_; }
  // The image's table, then the labels' own, kEntries each.
  const TransferTable& table() const { return table_; }
  const LabelCopy* labels() const { return labels_.get(); }
  const std::vector<LabelMaterial>& label_materials() const { return label_materials_; }
  // The second volume's table (empty without one in 3D).
  const TransferTable& fused_table() const { return fused_table_; }
  const std::vector<Light>& lights() const { return lights_.lights; }
  const EnvironmentDistribution& environment_distribution() const { return environment_; }

  // The scene with every pointer into host arrays (the prepared volume's
  // and this object's). Backends that keep copies elsewhere replace them.
  RenderScene HostView() const;

 private:
  void UpdateTables();
  void UpdateMajorants();
  std::vector<float> BuildMajorants() const;
  void UpdateFusedMajorants();

  std::shared_ptr<const PreparedVolume> volume_;
  Reconstruction reconstruction_ = Reconstruction::kTrilinear;
  TransferFunction tf_;
  std::shared_ptr<const LabelCopy> labels_;
  LabelSetup label_setup_;
  std::shared_ptr<const PreparedVolume> fused_;  // null: no second volume in 3D
  AffineMap fused_to_volume_;
  TransferTable fused_table_;
  std::vector<float> fused_majorants_;
  std::vector<LabelMaterial> label_materials_;  // by label value
  TransferTable table_;
  std::shared_ptr<const std::vector<float>> majorants_;
  std::uint64_t majorant_builds_ = 0;
  LightSetup lights_;
  EnvironmentDistribution environment_;
  ClipRegion clip_;
};

}  // namespace cinevol
