// The CPU backend: every core runs the shared per-pixel integrator.
#pragma once

#include "render/renderer.h"
#include "render/scene_data.h"

namespace cinevol {

class CpuRenderer final : public Renderer {
 public:
  explicit CpuRenderer(const RendererOptions& options = {})
      : threads_(options.cpu_threads), brick_size_(options.brick_size) {}

  Backend backend() const override { return Backend::kCpu; }
  void SetVolume(std::shared_ptr<const Volume> volume) override;
  void SetTransferFunction(const TransferFunction& tf) override { data_.SetTransferFunction(tf); }
  void SetLights(const LightSetup& lights) override { data_.SetLights(lights); }
  void SetClipRegion(const ClipRegion& clip) override { data_.SetClipRegion(clip); }
  void SetReconstruction(Reconstruction r) override { data_.SetReconstruction(r); }
  void SetLabels(std::shared_ptr<const LabelVolume> labels, const LabelSetup& setup) override;
  void SetFusion(std::shared_ptr<const Volume> fused, const FusionSetup& setup) override;
  void Render(const FrameRequest& request) override;
  void ResetAccumulation() override;
  int accumulated_frames() const override { return accumulated_frames_; }
  unsigned last_features() const override { return last_features_; }
  std::uint64_t majorant_builds() const override { return data_.majorant_builds(); }
  double LastFrameMilliseconds() const override { return last_ms_; }
  ImageRgbF Radiance() const override;
  ImageRgbF AccumulatedMean() const override;
  std::vector<Vec4f> FirstHits() const override { return first_hit_; }
  ImageRgbF Albedo() const override { return {width_, height_, albedo_}; }
  std::vector<Vec3f> SurfaceNormals() const override { return surface_normal_; }
  FrameTargets Targets() const override;
  // The tables the integrator reads here, for deterministic queries that must
  // classify the scene as it does (picking, server/reading/pick.h).
  const SceneData& scene_data() const { return data_; }

 private:
  int threads_;
  int brick_size_;
  std::shared_ptr<const VolumeCopy> volume_;  // the host copy every CPU renderer of the volume shares
  std::shared_ptr<const VolumeCopy> fused_;   // the second volume's, where there is one
  SceneData data_;
  int width_ = 0, height_ = 0;
  std::vector<Vec3f> radiance_, accumulated_, albedo_;
  std::vector<Vec3f> surface_normal_;  // where the last request asked for it
  std::vector<Vec4f> first_hit_;
  int accumulated_frames_ = 0;
  std::int64_t accumulated_samples_ = 0;  // per pixel: the accumulation is their sum
  unsigned last_features_ = 0;
  double last_ms_ = 0;
};

}  // namespace cinevol
