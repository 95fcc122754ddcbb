// Picker: the renderer's tables, a march of the optical depth along the ray,
// and the crossing refined by bisection inside the step that reached it.
#include "reading/pick.h"

#include <fmt/format.h>

#include <cmath>
#include <limits>

#include "core/error.h"
#include "render/classification.h"
#include "scene/scene_frame.h"

namespace cinevol {
namespace {

// Halvings of the step that crossed the threshold: 1/1024 of 0.25 voxel.
constexpr int kRefinements = 10;

// The medium along one ray: extinction and opacity at t from its origin, as the
// integrator classifies the scene.
template <bool kCubic, bool kWithLabels, bool kWithFusion>
class RayMedium {
 public:
  RayMedium(const RenderScene& scene, const Ray& ray) : s_(scene), ray_(ray) {}

  float SigmaT(float t) const {
    Classified c;
    return ExtinctionAt<kCubic, kWithLabels, kWithFusion>(s_, ray_.origin + ray_.direction * t, c);
  }

  // The tissue's opacity at t: what a capped face shows there.
  float Opacity(float t) const {
    Classified c;
    ExtinctionAt<kCubic, kWithLabels, kWithFusion>(s_, ray_.origin + ray_.direction * t, c);
    return MaterialOf<kWithLabels>(s_, c).opacity;  // a capped face cuts the volume's tissue
  }

 private:
  const RenderScene& s_;
  Ray ray_;
};

// One end of a trapezoid: where, the extinction there, the depth so far.
struct MarchPoint {
  float t, sigma_t, tau;
};

// Bisects [a, b), whose depth crosses `target` before b, down to the
// crossing; the trapezoid rule from a's side on each half keeps the depth
// the same function the march integrated.
template <class Depth>
float RefineCrossing(const Depth& depth, MarchPoint a, float t_b, float target) {
  for (int i = 0; i < kRefinements; ++i) {
    const float t = 0.5f * (a.t + t_b);
    const float sigma_t = depth.SigmaT(t);
    const float tau = a.tau + 0.5f * (a.sigma_t + sigma_t) * (t - a.t);
    if (tau >= target) {
      t_b = t;
    } else {
      a = {t, sigma_t, tau};
    }
  }
  return t_b;
}

// Where the accumulated opacity along `ray` reaches the threshold; nullopt
// where it never does inside what the volume box and the clipping keep.
template <bool kCubic, bool kWithLabels, bool kWithFusion>
std::optional<float> MarchToThreshold(const RenderScene& s, const Ray& ray, const PickSettings& settings) {
  float t0, t1;
  int entered;
  const Vec3f inv{1.0f / ray.direction.x, 1.0f / ray.direction.y, 1.0f / ray.direction.z};
  if (!IntersectBox(ray.origin, inv, s.volume.box_min, s.volume.box_max, t0, t1) ||
      !s.clip.Clip(ray.origin, ray.direction, t0, t1, &entered)) {
    return std::nullopt;
  }
  // Marched from the entry point: steps of a fraction of a voxel stay
  // steps however far the eye sits (a float t of 1e7 mm could not take them).
  const RayMedium<kCubic, kWithLabels, kWithFusion> depth(s, {ray.origin + ray.direction * t0, ray.direction});
  const float length = t1 - t0;
  // 1 - exp(-tau) >= threshold; a threshold of 1 makes it infinite.
  const float target =
      settings.threshold < 1.0f ? -std::log1p(-settings.threshold) : std::numeric_limits<float>::infinity();
  float tau = 0.0f;
  if (entered >= 0 && (s.clip.capped >> entered & 1u)) {
    // The integrator meets a capped face with the tissue's opacity as the
    // chance of a collision there: that share of the light stops at t0.
    const float cap = depth.Opacity(0.0f);
    if (cap >= settings.threshold) return t0;
    tau = -std::log1p(-cap);
  }
  const float step = settings.step_voxels * MinComponent(s.volume.spacing);
  MarchPoint a{0.0f, depth.SigmaT(0.0f), tau};
  while (a.t < length) {
    const float t = fminf(a.t + step, length);
    const float sigma_t = depth.SigmaT(t);
    const MarchPoint b{t, sigma_t, a.tau + 0.5f * (a.sigma_t + sigma_t) * (t - a.t)};
    if (b.tau >= target) return t0 + RefineCrossing(depth, a, b.t, target);
    a = b;
  }
  return std::nullopt;
}

using MarchFn = std::optional<float> (*)(const RenderScene&, const Ray&, const PickSettings&);

template <bool kCubic, bool kWithLabels>
MarchFn MarchWithFusion(const RenderScene& s) {
  return s.fused.present() ? &MarchToThreshold<kCubic, kWithLabels, true>
                           : &MarchToThreshold<kCubic, kWithLabels, false>;
}

MarchFn MarchFor(const RenderScene& s) {
  const bool labels = s.labels.voxels != nullptr;
  if (s.volume.tricubic) return labels ? MarchWithFusion<true, true>(s) : MarchWithFusion<true, false>(s);
  return labels ? MarchWithFusion<false, true>(s) : MarchWithFusion<false, false>(s);
}

// The label of a picked point: its nearest voxel's. A surface is found near
// its partial-volume boundary, often in the shell of unlabelled voxels that
// touch a label (and hide with it): the surface there is that label's, or
// where the shell touches several, the label a voxel further along the ray.
std::optional<PickedLabel> LabelAt(const LabelVolume& labels, const VolumeView& grid, const Ray& ray, float t) {
  auto stored_at = [&](float at) {
    return int(labels.labels[std::size_t(LabelView::NearestVoxel(grid, ray.origin + ray.direction * at))]);
  };
  int value = stored_at(t);
  if (value >= labels.first_derived && !labels.derived.empty()) {
    const DerivedLabel& d = labels.derived[std::size_t(value - labels.first_derived)];
    if (d.kind == DerivedLabel::Kind::kShell) {
      value = d.touches.size() == 1 ? d.touches[0] : stored_at(t + MinComponent(grid.spacing));
    }
  }
  const int label = labels.LabelOf(value);
  if (label == 0) return std::nullopt;
  const auto name = labels.names.find(label);
  return PickedLabel{label, name != labels.names.end() ? name->second : ""};
}

void CheckSettings(const PickSettings& settings) {
  if (!(settings.threshold > 0.0f && settings.threshold <= 1.0f)) {
    throw InputError(fmt::format("pick: threshold {} is outside (0, 1]", settings.threshold));
  }
  if (!(settings.step_voxels > 0.0f && settings.step_voxels <= 1.0f)) {
    throw InputError(fmt::format("pick: step {} voxels is outside (0, 1]", settings.step_voxels));
  }
}

}  // namespace

Picker::Picker(std::shared_ptr<const Volume> volume, std::shared_ptr<const LabelVolume> labels,
               const RenderSetup& setup)
    : volume_(std::move(volume)), labels_(std::move(labels)), camera_(setup.camera) {
  renderer_.SetVolume(volume_);
  renderer_.SetTransferFunction(setup.transfer_function);
  renderer_.SetClipRegion(setup.clip);
  renderer_.SetReconstruction(setup.reconstruction);
  renderer_.SetLabels(labels_, setup.labels);
  if (setup.fused_volume) {
    fused_ = setup.fused_volume;
    fusion_ = setup.fusion;
    renderer_.SetFusion(fused_, fusion_);
  }
}

PickResult Picker::PickPixel(int x, int y, const PickSettings& settings) const {
  if (x < 0 || y < 0 || x >= camera_.width || y >= camera_.height) {
    throw InputError(
        fmt::format("pick: pixel ({}, {}) is outside the {}x{} viewport", x, y, camera_.width, camera_.height));
  }
  return PickRay(camera_.GenerateRay(float(x) + 0.5f, float(y) + 0.5f, 0.5f, 0.5f), settings);
}

PickResult Picker::PickRay(const Ray& ray, const PickSettings& settings) const {
  CheckSettings(settings);
  const RenderScene scene = renderer_.scene_data().HostView();
  const std::optional<float> t = MarchFor(scene)(scene, ray, settings);
  return t ? Describe(ray, *t) : PickResult{};
}

PickResult Picker::Describe(const Ray& ray, float t) const {
  PickResult r;
  r.hit = true;
  r.distance_mm = t;
  r.position = ray.origin + ray.direction * t;
  r.position_lps = VolumePlacement::Of(*volume_).PointToPatient(r.position);
  const RenderScene scene = renderer_.scene_data().HostView();
  const PreparedVolume& prepared = renderer_.scene_data().volume();
  r.value = scene.volume.SampleTrilinear(r.position) * prepared.value_scale() + prepared.value_offset();
  if (labels_) r.label = LabelAt(*labels_, scene.volume, ray, t);
  if (fused_) r.fused_value = FusedValueAt(r.position);
  return r;
}

std::optional<float> Picker::FusedValueAt(Vec3f position) const {
  const Volume& fused = *fused_;
  const Vec3f q = fusion_.to_volume(position);  // its volume-centred frame
  const Vec3f half = fused.extent_mm() * 0.5f;
  if (!(std::abs(q.x) <= half.x && std::abs(q.y) <= half.y && std::abs(q.z) <= half.z)) return std::nullopt;
  // Trilinear on its voxels, as the overlay and the integrator sample it.
  const Vec3f v = (q + half) / fused.spacing_mm() - Vec3f{0.5f, 0.5f, 0.5f};
  const Vec3i lo{int(std::floor(v.x)), int(std::floor(v.y)), int(std::floor(v.z))};
  const Vec3f f = v - Vec3f{float(lo.x), float(lo.y), float(lo.z)};
  auto at = [&](int dx, int dy, int dz) {
    return fused.Value(std::clamp(lo.x + dx, 0, fused.dims().x - 1), std::clamp(lo.y + dy, 0, fused.dims().y - 1),
                       std::clamp(lo.z + dz, 0, fused.dims().z - 1));
  };
  float value = 0;
  for (int k = 0; k < 8; ++k) {
    const int dx = k & 1, dy = k >> 1 & 1, dz = k >> 2 & 1;
    value += at(dx, dy, dz) * (dx ? f.x : 1 - f.x) * (dy ? f.y : 1 - f.y) * (dz ? f.z : 1 - f.z);
  }
  return value * fusion_.value_factor;
}

}  // namespace cinevol
