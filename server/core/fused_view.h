// A second volume fused with the scene's (Scene.fusion; docs/time-and-fusion.md)
// as kernels see it: its voxels on its own grid, its own transfer table, and
// the affine map from the render frame (the scene volume's volume-centred mm)
// into its own volume-centred frame, where its VolumeView samples. Placed by
// both volumes' patient coordinates: the scene volume is never resampled.
#pragma once

#include "core/hd.h"
#include "core/transfer_function.h"
#include "core/transfer_view.h"
#include "core/vec.h"
#include "core/volume_view.h"

namespace cinevol {

// The render frame to the second volume's frame: q = x * p.x + y * p.y + z * p.z + offset.
struct AffineMap {
  Vec3f x{1, 0, 0}, y{0, 1, 0}, z{0, 0, 1}, offset{};

  CINEVOL_HD Vec3f operator()(Vec3f p) const { return x * p.x + y * p.y + z * p.z + offset; }
};

struct FusedView {
  VolumeView volume;  // voxels (or texture) unset: no second volume in 3D
  AffineMap to_volume;
  TransferView transfer;

  CINEVOL_HD bool present() const { return volume.voxels != nullptr || volume.texture != 0; }

  // Its extinction (per mm) at render-frame point p, 0 outside its box;
  // `entry` takes its table position there (kTextureOnly: VolumeView::SampleAs).
  template <bool kTextureOnly = false>
  CINEVOL_HD float SigmaT(Vec3f p, float& entry) const {
    const Vec3f q = to_volume(p);
    const bool inside = q.x >= volume.box_min.x && q.y >= volume.box_min.y && q.z >= volume.box_min.z &&
                        q.x <= volume.box_max.x && q.y <= volume.box_max.y && q.z <= volume.box_max.z;
    if (!inside) return 0.0f;
    entry = transfer.Entry(volume.template SampleAs<false, kTextureOnly>(q));
    return transfer.SigmaT(entry);
  }
};

// A second volume as renderers take it (Renderer::SetFusion), resolved from
// Scene.fusion against both volumes (scene/scene_builder.h, ResolveFusion).
struct FusionSetup {
  // In the second volume's own values (SUVbw already divided out): no
  // points, no second volume in 3D (slices only).
  TransferFunction transfer_function;
  AffineMap to_volume;  // the render frame to its volume-centred frame
  // What its values are multiplied by where shown (a PET's SUVbw factor with
  // Scene.fusion.suv, else 1): picks and the slices' overlay.
  float value_factor = 1;
};

}  // namespace cinevol
