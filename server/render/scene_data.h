// Host-side preparation shared by the CPU and CUDA renderers: the volume
// quantised to 16 bits, per-brick value ranges, the transfer table and the
// majorants it implies, lights and the environment map's sampling tables.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "core/lights.h"
#include "core/transfer_function.h"
#include "core/volume.h"
#include "render/render_scene.h"

namespace cinevol {

// Bricks are this many voxels along each axis by default: 4^3 measured
// faster than 8^3 and 16^3 on CPU and GPU (docs/performance.md).
inline constexpr int kDefaultBrickSize = 4;

// Min and max stored value of each brick, including the one-voxel margin that
// trilinear interpolation inside the brick reads.
struct BrickRanges {
  Vec3i bricks;
  std::vector<std::uint16_t> min, max;
};

BrickRanges ComputeBrickRanges(const std::uint16_t* voxels, Vec3i dims, Vec3i brick_size);

// Per-brick majorant: the largest extinction the table gives over the brick's
// value range (entries = stored * entry_scale + entry_offset).
std::vector<float> ComputeMajorants(const BrickRanges& ranges, const std::vector<float>& sigma_t,
                                    float entry_scale, float entry_offset);

// Sampling tables of an environment map (pbrt's Distribution2D).
struct EnvironmentDistribution {
  std::vector<Vec4f> texels;
  std::vector<float> weight, marginal_cdf, conditional_cdf;
  float weight_integral = 0;
};

EnvironmentDistribution BuildEnvironmentDistribution(const ImageRgbF& map);

class SceneData {
 public:
  // brick_size voxels per brick edge; 0 turns empty-space skipping off: one
  // brick with the global majorant, classic Woodcock tracking (to measure
  // what bricks buy).
  explicit SceneData(int brick_size = kDefaultBrickSize) : brick_size_setting_(brick_size) {}

  // Quantises float volumes to 16 bits over their range; 16-bit volumes are
  // used as they are (the Volume must outlive this object).
  void SetVolume(std::shared_ptr<const Volume> volume);
  void SetTransferFunction(const TransferFunction& tf);
  void SetLights(const LightSetup& setup);

  bool has_volume() const { return volume_ != nullptr; }
  Vec3i dims() const { return volume_->dims(); }
  const std::uint16_t* voxels() const { return voxels_; }
  std::size_t voxel_count() const { return volume_->voxel_count(); }
  const BrickRanges& brick_ranges() const { return bricks_; }
  const std::vector<float>& majorants() const { return majorants_; }
  // How many times the majorants were rebuilt (volume and transfer-function
  // changes): tests check that a camera move rebuilds none.
  std::uint64_t majorant_builds() const { return majorant_builds_; }
  const TransferTable& table() const { return table_; }
  const std::vector<Light>& lights() const { return lights_.lights; }
  const EnvironmentDistribution& environment_distribution() const { return environment_; }

  // The scene with every pointer into this object's host arrays. Backends
  // that keep copies elsewhere replace the pointers.
  RenderScene HostView() const;

 private:
  void UpdateMajorants();

  int brick_size_setting_;
  Vec3i brick_size_;
  std::shared_ptr<const Volume> volume_;
  std::vector<std::uint16_t> quantised_;  // float volumes only
  const std::uint16_t* voxels_ = nullptr;
  float value_scale_ = 1, value_offset_ = 0;  // value = stored * scale + offset
  BrickRanges bricks_;
  TransferFunction tf_;
  TransferTable table_;
  std::vector<float> majorants_;
  std::uint64_t majorant_builds_ = 0;
  LightSetup lights_;
  EnvironmentDistribution environment_;
};

}  // namespace cinevol
