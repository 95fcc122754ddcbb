// Piecewise-linear evaluation and table building.
#include "core/transfer_function.h"

#include <algorithm>
#include <cmath>

namespace cinevol {
namespace {

TransferPoint Mix(const TransferPoint& a, const TransferPoint& b, float t) {
  TransferPoint p;
  p.value = float(a.value + (double(b.value) - a.value) * t);
  p.opacity = a.opacity + (b.opacity - a.opacity) * t;
  p.diffuse = Lerp(a.diffuse, b.diffuse, t);
  p.specular = Lerp(a.specular, b.specular, t);
  p.roughness = a.roughness + (b.roughness - a.roughness) * t;
  p.emission = Lerp(a.emission, b.emission, t);
  return p;
}

}  // namespace

TransferPoint Evaluate(const TransferFunction& tf, float value) {
  const auto& pts = tf.points;
  if (pts.empty()) return {};
  if (value <= pts.front().value) return pts.front();
  if (value >= pts.back().value) return pts.back();
  const auto upper = std::upper_bound(pts.begin(), pts.end(), value,
                                      [](float v, const TransferPoint& p) { return v < p.value; });
  const TransferPoint& b = *upper;
  const TransferPoint& a = *(upper - 1);
  // In double: points may lie as far apart as float reaches (b - a overflows).
  return Mix(a, b, float((double(value) - a.value) / (double(b.value) - a.value)));
}

float MaxOpacity(const TransferFunction& tf, float lo, float hi) {
  float best = std::max(Evaluate(tf, lo).opacity, Evaluate(tf, hi).opacity);
  for (const TransferPoint& p : tf.points) {
    if (p.value > lo && p.value < hi) best = std::max(best, p.opacity);
  }
  return best;
}

TransferTable BuildTransferTable(const TransferFunction& tf, float value_min, float value_max, float max_sigma_t) {
  TransferTable t;
  t.value_min = value_min;
  // A constant volume still needs a range to map onto entries: one unit, or
  // where one unit is below the value's precision (|value| > 2^24), a
  // millionth of the value.
  t.value_max = value_max > value_min ? value_max
                                      : value_min + std::max(1.0f, std::abs(value_min) * 1e-6f);
  t.gradient_factor = std::min(tf.gradient_factor, kMaxGradientFactor);
  t.phase_g = tf.phase_g;
  const int n = TransferTable::kEntries;
  t.sigma_t.resize(n);
  t.diffuse_opacity.resize(n);
  t.specular_roughness.resize(n);
  t.emission.resize(n);
  for (int i = 0; i < n; ++i) {
    const float v = t.value_min + (t.value_max - t.value_min) * float(i) / float(n - 1);
    const TransferPoint p = Evaluate(tf, v);
    t.sigma_t[i] = std::min(p.opacity * tf.density_scale, max_sigma_t);
    t.diffuse_opacity[i] = ToVec4(p.diffuse, p.opacity);
    t.specular_roughness[i] = ToVec4(p.specular, p.roughness);
    t.emission[i] = ToVec4(p.emission, 0.0f);
    t.has_emission |= MaxComponent(p.emission) > 0.0f;
  }
  return t;
}

}  // namespace cinevol
