// Transfer function edits and evaluation for the viewer: see transfer_edits.h.
#include "transfer_edits.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cinevol::viewer {
namespace {

using Points = google::protobuf::RepeatedPtrField<v1::TransferFunctionPoint>;

// Where a value falls among the points: between points lo and hi, a fraction
// t of the way. Beyond the ends lo == hi (the end point) and t == 0.
struct Segment {
  int lo = 0;
  int hi = 0;
  float t = 0;
};

// Index of the first point whose value exceeds `value` (points.size() if none).
int UpperBound(const Points& points, float value) {
  auto it =
      std::upper_bound(points.begin(), points.end(), value,
                       [](float v, const v1::TransferFunctionPoint& p) { return v < p.value(); });
  return static_cast<int>(it - points.begin());
}

// Requires at least one point.
Segment Locate(const Points& points, float value) {
  const int n = points.size();
  const int i = UpperBound(points, value);
  if (i == 0) return {0, 0, 0};
  if (i == n) return {n - 1, n - 1, 0};
  const float a = points[i - 1].value(), b = points[i].value();
  return {i - 1, i, (value - a) / (b - a)};
}

float Mix(float a, float b, float t) { return a + (b - a) * t; }

v1::Color Mix(const v1::Color& a, const v1::Color& b, float t) {
  v1::Color c;
  c.set_r(Mix(a.r(), b.r(), t));
  c.set_g(Mix(a.g(), b.g(), t));
  c.set_b(Mix(a.b(), b.b(), t));
  return c;
}

// The material of a new point at `s`: every channel but value and opacity.
v1::TransferFunctionPoint MixMaterial(const Points& points, const Segment& s) {
  const v1::TransferFunctionPoint& a = points[s.lo];
  const v1::TransferFunctionPoint& b = points[s.hi];
  v1::TransferFunctionPoint p;
  *p.mutable_diffuse() = Mix(a.diffuse(), b.diffuse(), s.t);
  *p.mutable_specular() = Mix(a.specular(), b.specular(), s.t);
  p.set_roughness(Mix(a.roughness(), b.roughness(), s.t));
  *p.mutable_emission() = Mix(a.emission(), b.emission(), s.t);
  return p;
}

// A point for an empty function: white diffuse, no specular, no emission.
v1::TransferFunctionPoint NeutralMaterial() {
  v1::TransferFunctionPoint p;
  p.mutable_diffuse()->set_r(1);
  p.mutable_diffuse()->set_g(1);
  p.mutable_diffuse()->set_b(1);
  p.mutable_specular();
  p.set_roughness(0.5f);
  p.mutable_emission();
  return p;
}

// Moves the last element of `points` to `index`, shifting the rest up.
void MoveLastTo(Points& points, int index) {
  for (int i = points.size() - 1; i > index; --i) points.SwapElements(i, i - 1);
}

// Rounding can make scaled values collide; nudge each up past its predecessor.
void KeepStrictOrder(Points& points) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  for (int i = 1; i < points.size(); ++i) {
    const float previous = points[i - 1].value();
    if (points[i].value() <= previous) points[i].set_value(std::nextafter(previous, kInf));
  }
}

}  // namespace

float MinPointGap(const v1::TransferFunction& tf) {
  if (tf.points().empty()) return 1e-6f;
  const float front = tf.points(0).value(), back = tf.points(tf.points_size() - 1).value();
  const float magnitude = std::max(std::abs(front), std::abs(back));
  return std::max({(back - front) * 1e-4f, magnitude * 1e-6f, 1e-6f});
}

bool MoveTransferPoint(v1::TransferFunction& tf, int index, float value, float opacity) {
  const int n = tf.points_size();
  if (index < 0 || index >= n || !std::isfinite(value) || !std::isfinite(opacity)) return false;
  const float gap = MinPointGap(tf);
  constexpr float kMax = std::numeric_limits<float>::max();
  const float previous = index > 0 ? tf.points(index - 1).value() : -kMax;
  const float next = index + 1 < n ? tf.points(index + 1).value() : kMax;
  const float lo = previous + gap, hi = next - gap;
  // Neighbours closer than two gaps (only both exist then): stay in the middle.
  value = lo <= hi ? std::clamp(value, lo, hi) : 0.5f * (previous + next);
  v1::TransferFunctionPoint& p = *tf.mutable_points(index);
  p.set_value(value);
  p.set_opacity(std::clamp(opacity, 0.0f, 1.0f));
  tf.clear_preset();
  return true;
}

int AddTransferPoint(v1::TransferFunction& tf, float value, float opacity) {
  if (!std::isfinite(value)) return -1;
  const float gap = MinPointGap(tf);
  for (const auto& p : tf.points())
    if (std::abs(p.value() - value) < gap) return -1;
  v1::TransferFunctionPoint p = tf.points().empty()
                                    ? NeutralMaterial()
                                    : MixMaterial(tf.points(), Locate(tf.points(), value));
  p.set_value(value);
  p.set_opacity(std::isfinite(opacity) ? std::clamp(opacity, 0.0f, 1.0f) : 0.0f);
  const int index = UpperBound(tf.points(), value);
  *tf.add_points() = std::move(p);
  MoveLastTo(*tf.mutable_points(), index);
  tf.clear_preset();
  return index;
}

bool DeleteTransferPoint(v1::TransferFunction& tf, int index) {
  if (tf.points_size() <= 2 || index < 0 || index >= tf.points_size()) return false;
  tf.mutable_points()->DeleteSubrange(index, 1);
  tf.clear_preset();
  return true;
}

void ApplyWindowLevel(v1::TransferFunction& tf, float level_delta, float window_scale) {
  if (tf.points().empty()) return;
  if (!std::isfinite(level_delta)) level_delta = 0;
  // NaN or non-positive scales leave the window as it is.
  window_scale = window_scale > 0 ? std::clamp(window_scale, 0.05f, 20.0f) : 1.0f;
  const float centre = 0.5f * (tf.points(0).value() + tf.points(tf.points_size() - 1).value());
  for (auto& p : *tf.mutable_points())
    p.set_value(centre + level_delta + (p.value() - centre) * window_scale);
  KeepStrictOrder(*tf.mutable_points());
  tf.clear_preset();
}

float OpacityAt(const v1::TransferFunction& tf, float value) {
  if (tf.points().empty()) return 0;
  const Segment s = Locate(tf.points(), value);
  return Mix(tf.points(s.lo).opacity(), tf.points(s.hi).opacity(), s.t);
}

v1::Color DiffuseAt(const v1::TransferFunction& tf, float value) {
  if (tf.points().empty()) return {};
  const Segment s = Locate(tf.points(), value);
  return Mix(tf.points(s.lo).diffuse(), tf.points(s.hi).diffuse(), s.t);
}

}  // namespace cinevol::viewer
