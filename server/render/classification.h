// How the path tracer classifies a point of the scene: its extinction (per
// mm) and its material, from the reconstructed value, the transfer tables and
// the label there. Shared by the integrator and deterministic queries of the
// same scene (picking, server/reading/pick.h), so both see one opacity.
#pragma once

#include "core/hd.h"
#include "render/render_scene.h"

namespace cinevol {

// A point's classification: its transfer-table position and its label's style.
struct Classified {
  float entry = 0.0f;
  LabelMaterial label;
};

// The extinction (per mm) at p; `c` takes p's classification.
template <bool kCubic, bool kWithLabels>
CINEVOL_HD float ExtinctionAt(const RenderScene& s, Vec3f p, Classified& c) {
  c.entry = s.transfer.Entry(s.volume.template SampleAs<kCubic>(p));
  if constexpr (!kWithLabels) {
    return s.transfer.SigmaT(c.entry);
  } else {
    c.label = s.labels.At(s.volume, p);
    return fminf(c.label.opacity_scale * s.transfer.SigmaT(c.entry, c.label.table), s.transfer.max_sigma_t);
  }
}

// The material of a classified point: its label's table, opacity scale and colour.
template <bool kWithLabels>
CINEVOL_HD Material MaterialOf(const RenderScene& s, const Classified& c) {
  if constexpr (!kWithLabels) {
    return s.transfer.MaterialAt(c.entry);
  } else {
    Material m = s.transfer.MaterialAt(c.entry, c.label.table);
    m.opacity = fminf(1.0f, m.opacity * c.label.opacity_scale);
    if (c.label.has_color) m.diffuse = c.label.color;
    return m;
  }
}

}  // namespace cinevol
