// Picking on the 3D view: a deterministic ray through a pixel of the scene's
// camera, stopped where the opacity the path tracer sees along it reaches a
// threshold, answers the patient position there, the voxel value and the label.
//
// Opacity is the path tracer's own: the ray classifies the volume with the
// integrator's function (render/classification.h: reconstruction, transfer
// tables with the density scale and the extinction clamp, label styles, table
// removal), over the interval the clipping keeps, and accumulates
// 1 - exp(-integral of sigma_t ds): the probability that a camera path has
// collided by then. A capped clip face the ray enters through counts first
// with the tissue's opacity there, as the integrator makes it a surface with
// that probability. Gradients only choose how a collision scatters, never
// where it happens, so they play no part.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "core/camera.h"
#include "core/labels.h"
#include "core/volume.h"
#include "render/cpu_renderer.h"
#include "scene/scene_builder.h"

namespace cinevol {

struct PickSettings {
  // (0, 1]: the accumulated opacity at which the ray stops. 1 is reached
  // only on a capped clip face of fully opaque tissue; in the volume never
  // (the extinction clamp lets e^-32 through per voxel): no hit.
  float threshold = 0.5f;
  // (0, 1]: the march's step, in voxels of the smallest spacing; the crossing
  // is then refined inside the last step to 1/1024 of a step.
  float step_voxels = 0.25f;
};

struct PickedLabel {
  int value = 0;     // the segmentation's label (never 0, the background)
  std::string name;  // from the label table; "" when it names none
};

struct PickResult {
  bool hit = false;
  Vec3f position_lps;     // patient LPS mm
  Vec3f position;         // the volume-centred frame the renderers work in (mm)
  float distance_mm = 0;  // from the ray's origin (the eye)
  // The volume's value there in its units (HU for CT), reconstructed
  // trilinearly whatever the scene's reconstruction: it equals the voxel's
  // value at a voxel centre, as a reader expects.
  float value = 0;
  // The segmentation's label there: the nearest voxel's, or on the shell of
  // unlabelled voxels around a label (where surfaces are found) that label's.
  // None for the background, the table or without a segmentation.
  std::optional<PickedLabel> label;
  // The second volume's value there (Scene.fusion; times its value factor,
  // SUVbw for a PET), linear on its own grid; none without one or outside it.
  std::optional<float> fused_value;
};

class Picker {
 public:
  // `setup`: the scene resolved against `volume` (ResolveScene; its fusion
  // with ResolveFusion where it fuses a second volume), its camera in the
  // volume-centred frame; `labels`: the volume's segmentation (with the
  // table where the scene removes it), or null.
  Picker(std::shared_ptr<const Volume> volume, std::shared_ptr<const LabelVolume> labels, const RenderSetup& setup);

  // The ray through the centre of pixel (x, y) of the setup's camera (through
  // the lens's centre: the pinhole ray). Throws InputError for a pixel
  // outside the viewport or a setting out of range.
  PickResult PickPixel(int x, int y, const PickSettings& settings = {}) const;
  // Any ray in the volume-centred frame; its direction is unit length.
  PickResult PickRay(const Ray& ray, const PickSettings& settings = {}) const;

  const Camera& camera() const { return camera_; }

 private:
  PickResult Describe(const Ray& ray, float t) const;
  std::optional<float> FusedValueAt(Vec3f position) const;

  std::shared_ptr<const Volume> volume_;
  std::shared_ptr<const LabelVolume> labels_;
  std::shared_ptr<const Volume> fused_;  // the second volume, where the scene fuses one
  FusionSetup fusion_;
  Camera camera_;
  CpuRenderer renderer_;  // never renders: it holds the scene's tables as the integrator reads them
};

}  // namespace cinevol
