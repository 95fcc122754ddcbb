// The second volume's start and glow: see second_volume.h.
#include "viewer/second_volume.h"

#include <algorithm>

namespace cinevol::viewer {
namespace {

// A point of the glow: a warm diffuse colour, emitting `glow` times its full warmth.
v1::TransferFunctionPoint GlowPoint(float value, float opacity, float glow) {
  v1::TransferFunctionPoint p;
  p.set_value(value);
  p.set_opacity(opacity);
  v1::Color& diffuse = *p.mutable_diffuse();
  diffuse.set_r(1), diffuse.set_g(0.4f), diffuse.set_b(0.1f);
  v1::Color& emission = *p.mutable_emission();
  emission.set_r(6 * glow), emission.set_g(2.4f * glow), emission.set_b(0.5f * glow);
  return p;
}

}  // namespace

v1::TransferFunction GlowOf(const v1::VolumeInfo& fused) {
  const bool suv = fused.suv_factor() > 0;
  const float lo = suv ? 2.5f : fused.min_value() + 0.3f * (fused.max_value() - fused.min_value());
  const float hi = suv ? 10.0f : fused.max_value();
  v1::TransferFunction tf;
  *tf.add_points() = GlowPoint(lo, 0, 0);
  *tf.add_points() = GlowPoint(std::max(hi, lo + 1e-3f), 0.4f, 1);
  tf.set_density_scale(1);
  return tf;
}

v1::Fusion FusedStart(const v1::VolumeInfo& fused, bool align_by_patient) {
  v1::Fusion fusion;
  fusion.set_volume_id(fused.id());
  fusion.set_align_by_patient(align_by_patient);
  fusion.set_suv(fused.suv_factor() > 0);
  *fusion.mutable_transfer_function() = GlowOf(fused);
  fusion.mutable_overlay()->set_color_map(v1::HOT);
  fusion.mutable_overlay()->set_opacity(0.5f);
  return fusion;
}

bool Glows(const v1::Fusion& fusion) { return fusion.transfer_function().points_size() > 0; }

void SetGlow(v1::Fusion& fusion, bool glow, const v1::VolumeInfo& fused) {
  if (glow) {
    *fusion.mutable_transfer_function() = GlowOf(fused);
  } else {
    fusion.clear_transfer_function();
  }
}

}  // namespace cinevol::viewer
