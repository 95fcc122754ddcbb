// How the path tracer classifies a point of the scene: its extinction (per
// mm) and its material, from the reconstructed value, the transfer tables,
// the label there and a second volume's own (Scene.fusion). Shared by the
// integrator and deterministic queries of the same scene (picking,
// server/reading/pick.h), so both see one opacity.
#pragma once

#include "core/hd.h"
#include "render/render_scene.h"

namespace cinevol {

// A point's classification: its transfer-table position and its label's
// style; with a second volume, its table position there and its share of
// the extinction.
struct Classified {
  float entry = 0.0f;
  LabelMaterial label;
  float fused_entry = 0.0f;
  float fused_share = 0.0f;  // the second volume's extinction / the sum
  // A collision met the second volume (the integrator draws it with
  // probability fused_share): its material, not the scene volume's.
  bool fused = false;
};

// The extinction (per mm) at p; `c` takes p's classification. With a second
// volume the two media mix: their extinctions add. kTextureOnly: both volumes
// are read through their textures (VolumeView::SampleAs).
template <bool kCubic, bool kWithLabels, bool kWithFusion = false, bool kTextureOnly = false>
CINEVOL_HD float ExtinctionAt(const RenderScene& s, Vec3f p, Classified& c) {
  c.entry = s.transfer.Entry(s.volume.template SampleAs<kCubic, kTextureOnly>(p));
  float sigma;
  if constexpr (!kWithLabels) {
    sigma = s.transfer.SigmaT(c.entry);
  } else {
    c.label = s.labels.At(s.volume, p);
    sigma = fminf(c.label.opacity_scale * s.transfer.SigmaT(c.entry, c.label.table), s.transfer.max_sigma_t);
  }
  if constexpr (kWithFusion) {
    const float fused = s.fused.template SigmaT<kTextureOnly>(p, c.fused_entry);
    const float total = sigma + fused;
    c.fused_share = total > 0.0f ? fused / total : 0.0f;
    return total;
  }
  return sigma;
}

// The material of a classified point: its label's table, opacity scale and
// colour; the second volume's where a collision met it.
template <bool kWithLabels, bool kWithFusion = false>
CINEVOL_HD Material MaterialOf(const RenderScene& s, const Classified& c) {
  if constexpr (kWithFusion) {
    if (c.fused) return s.fused.transfer.MaterialAt(c.fused_entry);
  }
  if constexpr (!kWithLabels) {
    return s.transfer.MaterialAt(c.entry);
  } else {
    Material m = s.transfer.MaterialAt(c.entry, c.label.table);
    m.opacity = fminf(1.0f, m.opacity * c.label.opacity_scale);
    if (c.label.has_color) m.diffuse = c.label.color;
    return m;
  }
}

// The radiance a classified point emits.
template <bool kWithLabels, bool kWithFusion = false>
CINEVOL_HD Vec3f EmissionOf(const RenderScene& s, const Classified& c) {
  if constexpr (kWithFusion) {
    if (c.fused) return s.fused.transfer.Emission(c.fused_entry);
  }
  return s.transfer.Emission(c.entry, kWithLabels ? c.label.table : 0);
}

}  // namespace cinevol
