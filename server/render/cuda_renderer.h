// The CUDA backend: the shared per-pixel integrator as one kernel per
// feature set. Scene data live in device memory, uploaded when they change
// (the voxels and the majorants once per GPU, shared with every renderer
// there: VolumeCache); frames stay on the device for the CUDA denoiser.
#pragma once

#include <memory>

#include "render/renderer.h"
#include "render/scene_data.h"

namespace cinevol {

class CudaRenderer final : public Renderer {
 public:
  explicit CudaRenderer(const RendererOptions& options = {});
  ~CudaRenderer() override;

  Backend backend() const override { return Backend::kCuda; }
  void SetVolume(std::shared_ptr<const Volume> volume) override;
  void SetTransferFunction(const TransferFunction& tf) override;
  void SetLights(const LightSetup& lights) override;
  void SetClipRegion(const ClipRegion& clip) override { data_.SetClipRegion(clip); }
  void SetReconstruction(Reconstruction r) override;
  void SetLabels(std::shared_ptr<const LabelVolume> labels, const LabelSetup& setup) override;
  void SetFusion(std::shared_ptr<const Volume> fused, const FusionSetup& setup) override;
  void Render(const FrameRequest& request) override;
  void ResetAccumulation() override;
  int accumulated_frames() const override { return accumulated_frames_; }
  unsigned last_features() const override { return last_features_; }
  std::uint64_t majorant_builds() const override { return data_.majorant_builds(); }
  double LastFrameMilliseconds() const override;
  ImageRgbF Radiance() const override;
  ImageRgbF AccumulatedMean() const override;
  std::vector<Vec4f> FirstHits() const override;
  ImageRgbF Albedo() const override;
  std::vector<Vec3f> SurfaceNormals() const override;
  FrameTargets Targets() const override;

 private:
  int brick_size_;
  bool use_texture_;  // RendererOptions::volume_texture
  // The voxels and majorants on this GPU, shared. Declared before device_:
  // the frames in flight end (~Device) before they may go.
  std::shared_ptr<const VolumeCopy> volume_;
  std::shared_ptr<const VolumeCopy> fused_;  // the second volume's, where there is one
  std::shared_ptr<const float> majorants_;
  struct Device;  // CUDA objects; defined in the .cu file
  std::unique_ptr<Device> device_;
  void UploadTables();  // the transfer tables and the majorants, after SceneData changed them
  void AcquireMajorants();
  template <class T>
  std::vector<T> Download(const T* frame_scratch) const;  // the last frame's, to the host

  SceneData data_;
  int width_ = 0, height_ = 0;
  int accumulated_frames_ = 0;
  std::int64_t accumulated_samples_ = 0;  // per pixel: the accumulation is their sum
  unsigned last_features_ = 0;
};

}  // namespace cinevol
